// `inr`: the engine's command-line front end (no VTK). See README.md for usage.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>

#include "Args.h"
#include "Commands.h"
#include "Model/InrModel.h"

#ifdef __linux__
#include <unistd.h>
#endif

namespace {

const char* kUsage =
    "usage: inr <command> [options]\n"
    "commands:\n"
    "  info   MODEL [--json]                 architecture, parameters, domain, time and value range\n"
    "  eval   MODEL --time T [--points FILE] evaluate at world-space 'x y z' lines (stdin by default)\n"
    "  slice  MODEL --time T -o OUT.png      2D slice image (see 'inr slice --help')\n"
    "  render MODEL -o OUT.png|.pfm          volume rendering (see 'inr render --help')\n";

// The CPU backend's OpenMP threads, by libgomp's default, spin at every barrier before they sleep.
// On a machine with other work, a spinning thread holds a core that the thread it waits for needs,
// and a frame of small wavefront batches (dozens of barriers) then waits scheduler slices: two
// renders side by side ran 5x slower than with sleeping waits (Docs/cli.md). libgomp reads its
// wait policy once, when it is loaded, before main; so the CLI runs itself again with
// OMP_WAIT_POLICY=passive, unless the user has chosen a policy (OMP_WAIT_POLICY or
// GOMP_SPINCOUNT set: then they are respected as given).
void preferSleepingOpenMpWaits(char** argv) {
#ifdef __linux__
  if (std::getenv("OMP_WAIT_POLICY") || std::getenv("GOMP_SPINCOUNT")) return;
  setenv("OMP_WAIT_POLICY", "passive", 1);
  execv("/proc/self/exe", argv);  // returns only if it failed: go on under the default policy
  unsetenv("OMP_WAIT_POLICY");
#else
  (void)argv;
#endif
}

}  // namespace

int main(int argc, char** argv) {
  preferSleepingOpenMpWaits(argv);
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
