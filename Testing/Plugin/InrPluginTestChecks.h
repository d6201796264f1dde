// The plain (not GoogleTest) plugin test programs' checks: one "ok: WHAT" or "FAIL: WHAT" line
// each, the failures counted for the program's exit status (header-only, test code).
#ifndef InrPluginTestChecks_h
#define InrPluginTestChecks_h

#include <cstdio>
#include <string>

namespace inr_plugin_test
{
inline int failures = 0;

inline void check(bool ok, const std::string& what)
{
  std::printf("%s: %s\n", ok ? "ok" : "FAIL", what.c_str());
  if (!ok)
  {
    ++failures;
  }
}
}

#endif
