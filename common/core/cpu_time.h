#pragma once

#include <ctime>

namespace ag {

/// CPU time of the calling thread (ms). Unlike wall time it excludes the time
/// the thread was preempted, which dominates on a machine shared with other
/// jobs; benchmarks time with it.
inline double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

}  // namespace ag
