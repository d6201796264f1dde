// `inr`: the engine's command-line front end (no VTK). See README.md for usage.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "Args.h"
#include "Commands.h"
#include "Model/InrModel.h"

namespace {

const char* kUsage =
    "usage: inr <command> [options]\n"
    "commands:\n"
    "  info   MODEL [--json]                 architecture, parameters, domain, time and value range\n"
    "  eval   MODEL --time T [--points FILE] evaluate at world-space 'x y z' lines (stdin by default)\n"
    "  slice  MODEL --time T -o OUT.png      2D slice image (see 'inr slice --help')\n"
    "  render MODEL -o OUT.png|.pfm          volume rendering (see 'inr render --help')\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h")) {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  try {
    if (command == "info") return inr::cli::runInfo(argc - 2, argv + 2);
    if (command == "eval") return inr::cli::runEval(argc - 2, argv + 2);
    if (command == "slice") return inr::cli::runSlice(argc - 2, argv + 2);
    if (command == "render") return inr::cli::runRender(argc - 2, argv + 2);
    std::fprintf(stderr, "inr: unknown command '%s'\n%s", command.c_str(), kUsage);
    return 2;
  } catch (const inr::cli::UsageError& e) {
    std::fprintf(stderr, "inr %s: %s\n", command.c_str(), e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "inr %s: error: %s\n", command.c_str(), e.what());
    return 1;
  }
}
