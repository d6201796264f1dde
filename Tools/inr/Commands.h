#pragma once
// Subcommands of the `inr` CLI. Each takes the arguments after the subcommand name and returns
// the process exit code (0 success, 1 runtime error, 2 usage error).
namespace inr::cli {
int runInfo(int argc, char** argv);
int runEval(int argc, char** argv);
int runSlice(int argc, char** argv);
int runRender(int argc, char** argv);
}  // namespace inr::cli
using inr::cli::runRender;
