#include "Args.h"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace inr::cli {

Args::Args(int argc, char** argv, std::set<std::string> valued, std::set<std::string> flags)
    : Args(std::vector<std::string>(argv, argv + argc), valued, flags) {}

Args::Args(const std::vector<std::string>& argv, const std::set<std::string>& valued,
           const std::set<std::string>& flags) {
  const int argc = int(argv.size());
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a.size() > 2 && a.compare(0, 2, "--") == 0) {
      std::string name = a.substr(2), value;
      const auto eq = name.find('=');
      const bool inlineValue = eq != std::string::npos;
      if (inlineValue) {
        value = name.substr(eq + 1);
        name = name.substr(0, eq);
      }
      if (valued.count(name)) {
        if (!inlineValue) {
          if (i + 1 >= argc) throw UsageError("option --" + name + " needs a value");
          value = argv[++i];
        }
        values_[name] = value;
      } else if (flags.count(name) && !inlineValue) {
        flagsSet_.insert(name);
      } else {
        throw UsageError("unknown option --" + name);
      }
    } else if (a == "-o") {
      if (i + 1 >= argc) throw UsageError("option -o needs a file name");
      values_["output"] = argv[++i];
    } else {
      positional_.push_back(a);
    }
  }
}

std::string Args::get(const std::string& name, const std::string& dflt) const {
  auto it = values_.find(name);
  return it == values_.end() ? dflt : it->second;
}

double parseDouble(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw UsageError(what + ": '" + text + "' is not a finite number");
  return v;
}

long parseInt(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0') throw UsageError(what + ": '" + text + "' is not an integer");
  return v;
}

double Args::getDouble(const std::string& name, double dflt) const {
  return has(name) ? parseDouble(get(name), "--" + name) : dflt;
}

long Args::getInt(const std::string& name, long dflt) const {
  return has(name) ? parseInt(get(name), "--" + name) : dflt;
}

std::vector<double> Args::getList(const std::string& name, std::size_t count) const {
  std::vector<double> out;
  std::stringstream s(get(name));
  std::string item;
  while (std::getline(s, item, ',')) out.push_back(parseDouble(item, "--" + name));
  if (count && out.size() != count)
    throw UsageError("--" + name + " needs " + std::to_string(count) + " comma-separated numbers, got " +
                     std::to_string(out.size()));
  return out;
}

}  // namespace inr::cli
