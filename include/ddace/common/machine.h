// What benchmark reports say about the machine they ran on: it is shared, so absolute
// times move with its load, and a report states the load and the time it was written.
#pragma once

#include <ctime>
#include <sstream>
#include <string>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

namespace ddace {

/// The 1-minute load average from /proc/loadavg ("unknown" where there is none).
inline std::string loadAverage() {
  std::string first;
  try {
    std::istringstream(readTextFile("/proc/loadavg", 4096)) >> first;
  } catch (const Error&) {
  }
  return first.empty() ? "unknown" : first;
}

/// Now in UTC, formatted by strftime's `format` (default "YYYY-MM-DD HH:MM UTC"; at most 63 characters).
inline std::string utcNow(const char* format = "%Y-%m-%d %H:%M UTC") {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, format, &tm);
  return buf;
}

}  // namespace ddace
