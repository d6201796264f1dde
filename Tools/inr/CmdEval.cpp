#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <vector>

#include "Args.h"
#include "Commands.h"
#include "Evaluator/CpuInrEvaluator.h"
#include "Model/InrModel.h"

namespace inr::cli {

// Reads world-space points, one `x y z` per line; blank lines and lines starting with '#' are
// skipped. A malformed line (not exactly three numbers, a NaN or infinite coordinate, one beyond
// the fp32 range) is an error naming the source and line number. No points is not an error: the
// output is empty.
static std::vector<QueryPoint> readPoints(std::istream& in, const std::string& source, float t) {
  std::vector<QueryPoint> pts;
  std::string line;
  for (long lineNo = 1; std::getline(in, line); ++lineNo) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = source + ":" + std::to_string(lineNo) + ": ";
    std::istringstream s(line);
    std::vector<std::string> tokens;
    for (std::string tok; s >> tok;) tokens.push_back(tok);
    if (tokens.size() != 3)
      throw std::runtime_error(where + "expected three numbers 'x y z', got " + std::to_string(tokens.size()) +
                               " field(s): '" + line + "'");
    double xyz[3];
    for (int i = 0; i < 3; ++i) {
      const std::string& tok = tokens[i];
      char* end = nullptr;
      errno = 0;
      xyz[i] = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0')
        throw std::runtime_error(where + "'" + tok + "' is not a number (expected 'x y z')");
      const bool overflow = errno == ERANGE && std::isinf(xyz[i]);  // e.g. 1e999; underflow reads as ~0
      if (overflow || (std::isfinite(xyz[i]) && std::fabs(xyz[i]) > std::numeric_limits<float>::max()))
        throw std::runtime_error(where + "coordinate '" + tok + "' is outside the fp32 range the evaluator uses");
      if (!std::isfinite(xyz[i]))
        throw std::runtime_error(where + "coordinate '" + tok + "' is not finite (NaN and infinite points cannot "
                                 "be evaluated)");
    }
    pts.push_back({float(xyz[0]), float(xyz[1]), float(xyz[2]), t});
  }
  return pts;
}

int runEval(int argc, char** argv) {
  Args args(argc, argv, {"time", "points", "threads"}, {"help"});
  if (args.has("help")) {
    std::puts("usage: inr eval MODEL --time T [--points FILE] [--threads N]\n"
              "Reads world-space points 'x y z' (one per line; stdin unless --points) and prints the\n"
              "field value at world time T for each, one per line, at full float precision.\n"
              "Blank lines and lines starting with '#' are skipped; no points gives no output (exit 0).\n"
              "A line that is not three finite numbers is an error naming its line number.");
    return 0;
  }
  if (args.positional().size() != 1) throw UsageError("expects exactly one MODEL file");
  if (!args.has("time")) throw UsageError("--time T is required (world time)");
  const InrModel model = InrModel::loadFile(args.positional()[0]);
  const double t = args.getDouble("time", 0.0);
  if (model.domain.usesTime() && (t < model.domain.timeBegin || t > model.domain.timeEnd))
    std::fprintf(stderr, "inr eval: warning: --time %g is outside the model's time range [%g, %g] (extrapolating)\n",
                 t, model.domain.timeBegin, model.domain.timeEnd);
  std::vector<QueryPoint> pts;
  if (args.has("points")) {
    std::ifstream in(args.get("points"));
    if (!in) throw std::runtime_error(args.get("points") + ": cannot open points file");
    pts = readPoints(in, args.get("points"), float(t));
  } else {
    pts = readPoints(std::cin, "<stdin>", float(t));
  }
  CpuEvaluatorOptions opts;
  opts.threads = static_cast<int>(args.getInt("threads", 0));
  const CpuInrEvaluator evaluator(model, opts);
  std::vector<float> values(pts.size());
  evaluator.evaluate(pts.data(), pts.size(), values.data());
  std::string out;
  char buf[32];
  for (float v : values) {
    std::snprintf(buf, sizeof buf, "%.9g\n", v);
    out += buf;
  }
  std::fwrite(out.data(), 1, out.size(), stdout);
  return std::fflush(stdout) == 0 ? 0 : 1;
}

}  // namespace inr::cli
