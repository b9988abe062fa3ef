// Running a Python reference implementation in the same benchmark run: its command's
// output, and numbers from the one-line JSON object it prints.
#pragma once

#include <cstdio>
#include <string>

#include "ddace/common/error.h"

namespace ddace::bench {

/// Standard output of `command`; throws ddace::Error when it cannot run or fails.
inline std::string capture(const std::string& command) {
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) throw Error("cannot run: " + command);
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, pipe)) out.append(buf, n);
  if (pclose(pipe) != 0) throw Error("failed: " + command + "\n" + out);
  return out;
}

/// The number after "key": in a flat JSON object.
inline double jsonNumber(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\":");
  if (at == std::string::npos) throw Error("reference output lacks '" + key + "': " + json);
  return std::stod(json.substr(at + key.size() + 3));
}

}  // namespace ddace::bench
