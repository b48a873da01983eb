#pragma once
/// @file
/// CPU time, for the benchmark programs and the figures a component keeps on itself (never for
/// tests: tests never measure time).

#include <time.h>

namespace autodrive {

/// CPU seconds the calling thread has used.
inline double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace autodrive
