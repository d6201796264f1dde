#pragma once
// Minimal command-line parsing for the `inr` subcommands: positionals, `--name value` options
// and `--flag` switches, with errors that name the offending argument.
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace inr::cli {

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Args {
public:
  // `valued`: options that take a value; `flags`: switches.
  Args(int argc, char** argv, std::set<std::string> valued, std::set<std::string> flags);
  Args(const std::vector<std::string>& args, const std::set<std::string>& valued, const std::set<std::string>& flags);
  const std::vector<std::string>& positional() const { return positional_; }
  bool has(const std::string& name) const { return values_.count(name) || flagsSet_.count(name); }
  std::string get(const std::string& name, const std::string& dflt = "") const;
  double getDouble(const std::string& name, double dflt) const;
  long getInt(const std::string& name, long dflt) const;
  // Comma-separated numbers, exactly `count` of them (0 = any).
  std::vector<double> getList(const std::string& name, std::size_t count) const;

private:
  std::vector<std::string> positional_;
  std::map<std::string, std::string> values_;
  std::set<std::string> flagsSet_;
};

double parseDouble(const std::string& text, const std::string& what);
long parseInt(const std::string& text, const std::string& what);

}  // namespace inr::cli
