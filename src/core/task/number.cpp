#include "number.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace ddace::task::detail {

std::string shortestNumber(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string csvNumber(double v) {
  char buf[64];
  const int len = std::snprintf(buf, sizeof buf, "%.6f", v);
  double back = 0;
  if (len > 0 && len < static_cast<int>(sizeof buf) && parseFiniteNumber(std::string_view(buf, len), back) &&
      back == v && !(v == 0 && std::signbit(v)))
    return std::string(buf, static_cast<size_t>(len));
  return shortestNumber(v);
}

bool parseFiniteNumber(std::string_view text, double& out) {
  if (text.empty() || text.size() > 64) return false;
  // strtod needs a terminated string and stops at the first byte it cannot use: parse a
  // copy and require that it used every byte (a NUL inside the field is not the end).
  char buf[65];
  text.copy(buf, text.size());
  buf[text.size()] = '\0';
  if (std::isspace(static_cast<unsigned char>(buf[0]))) return false;
  char* end = nullptr;
  const double v = std::strtod(buf, &end);
  if (end != buf + text.size() || !std::isfinite(v)) return false;
  out = v;
  return true;
}

}  // namespace ddace::task::detail
