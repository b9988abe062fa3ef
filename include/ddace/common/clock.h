// Clocks for intervals inside one process: timeouts, link timestamps and benchmark
// timings. Never wall time (a clock step must not fire a timeout or skew a timing);
// code that decides on time takes it as an argument, these read it at the edges.
#pragma once

#include <time.h>

#include <chrono>

namespace ddace {

using SteadyClock = std::chrono::steady_clock;

/// Seconds on the steady (monotonic) clock since an unspecified start; only
/// differences mean something.
inline double monotonicS() {
  return std::chrono::duration<double>(SteadyClock::now().time_since_epoch()).count();
}

/// Milliseconds of steady-clock time since `t0`.
inline double msSince(SteadyClock::time_point t0) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - t0).count();
}

/// CPU seconds the calling thread has run: the work itself, without the time it waited
/// for a core on a loaded machine.
inline double threadCpuS() {
  timespec ts{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// CPU seconds this process has run, all threads together.
inline double processCpuS() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace ddace
