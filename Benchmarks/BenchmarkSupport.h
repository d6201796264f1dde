#pragma once
// What the benchmark programs share: walking the command line, the spread of repeated
// measurements, and loading the model files they are given.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "Model/InrModel.h"

namespace inr::bench {

// argv option by option:
//   for (CommandLine cl(argc, argv); !cl.done();) {
//     const std::string a = cl.next();
//     if (a == "--reps") reps = std::stoi(cl.value());
//     ...
class CommandLine {
public:
  CommandLine(int argc, char** argv) : argc_(argc), argv_(argv) {}
  bool done() const { return i_ >= argc_; }
  const std::string& next() { return current_ = argv_[i_++]; }
  // The value following the option just read; exits with status 2 when there is none.
  std::string value() {
    if (i_ >= argc_) {
      std::fprintf(stderr, "%s needs a value\n", current_.c_str());
      std::exit(2);
    }
    return argv_[i_++];
  }

  // What every benchmark does with an argument none of its own options took: -h / --help prints
  // `usage` (returns 0), another "-..." is an unknown option (returns 2), anything else is a
  // model path (appended to `models`; returns -1: parsing goes on). Non-negative results are the
  // program's exit status.
  int other(const std::string& a, const char* usage, std::vector<std::string>& models) const {
    if (a == "-h" || a == "--help") {
      std::fputs(usage, stdout);
      return 0;
    }
    if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "unknown option %s (see --help)\n", a.c_str());
      return 2;
    }
    models.push_back(a);
    return -1;
  }

private:
  int argc_;
  char** argv_;
  int i_ = 1;
  std::string current_;
};

// Median (the upper one of an even count), minimum and maximum of repeated measurements.
struct Spread {
  double median = 0, lo = 0, hi = 0;
};

inline Spread spreadOf(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return {v[v.size() / 2], v.front(), v.back()};
}

inline double medianOf(std::vector<double> v) { return spreadOf(std::move(v)).median; }

// Model files, each named by its file name.
inline std::vector<std::pair<std::string, InrModel>> loadModelFiles(const std::vector<std::string>& paths) {
  std::vector<std::pair<std::string, InrModel>> out;
  for (const auto& p : paths) out.emplace_back(std::filesystem::path(p).filename().string(), InrModel::loadFile(p));
  return out;
}

}  // namespace inr::bench
