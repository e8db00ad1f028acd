#pragma once

#include <cstdio>
#include <cstdlib>

// A property a fuzz target checks on every input: when it does not hold, the input is reported
// with what failed and the run aborts (libFuzzer keeps the input as a crash).
inline void FuzzCheck(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "check failed: %s\n", what);
    std::abort();
  }
}
