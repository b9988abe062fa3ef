// Peak-memory measurement shared by the memory benches (csv_memory, label_memory): this
// process's peak resident set around a call, a tool's in a child process, and the scratch
// folder both write their large files into.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

#include "ddace/common/error.h"

namespace ddace::bench {

/// A kB value of /proc/self/status ("VmHWM", "VmRSS"); -1 where absent.
inline long statusKb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) return std::stol(line.substr(key.size() + 1));
  return -1;
}

/// Resets VmHWM to the current resident set; false where the kernel cannot.
inline bool resetPeak() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  clear.flush();
  return static_cast<bool>(clear);
}

/// A tool run in a child process: its peak resident set (kB, from wait4), wall time and
/// exit status (-1 when it did not exit).
struct ChildRun {
  long peak_kb = 0;
  double seconds = 0;
  int status = -1;
};

/// Runs `argv` (argv[0] a path) with stdout to /dev/null and stderr to `stderr_path`
/// ("" = inherited).
inline ChildRun runChild(const std::vector<std::string>& argv, const std::string& stderr_path = "") {
  ChildRun r;
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) throw Error("fork failed");
  if (pid == 0) {
    if (!std::freopen("/dev/null", "w", stdout)) ::_exit(126);
    if (!stderr_path.empty() && !std::freopen(stderr_path.c_str(), "w", stderr)) ::_exit(126);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int wstatus = 0;
  rusage usage{};
  if (::wait4(pid, &wstatus, 0, &usage) != pid) throw Error("wait4 failed");
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.peak_kb = usage.ru_maxrss;
  r.status = WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1;
  return r;
}

/// A fresh folder under the system's temporary directory, removed with everything in it
/// when this goes out of scope (the benches write hundreds of MB into it).
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

/// `v` with `decimals` digits after the point.
inline std::string fixed(double v, int decimals) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(decimals) << v;
  return s.str();
}

/// kB as MB with one decimal.
inline std::string mb(long kb) {
  return fixed(kb / 1024.0, 1);
}

}  // namespace ddace::bench
