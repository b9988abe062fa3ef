// What benchmark reports say about the machine they ran on: it is shared, so absolute
// times move with its load, and a report states the load and the time it was written.
#pragma once

#include <ctime>
#include <fstream>
#include <string>

namespace ddace {

/// The 1-minute load average from /proc/loadavg ("unknown" where there is none).
inline std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string first;
  in >> first;
  return first.empty() ? "unknown" : first;
}

/// Now, as "YYYY-MM-DD HH:MM UTC".
inline std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M UTC", &tm);
  return buf;
}

}  // namespace ddace
