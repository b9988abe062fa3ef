// Running the real `ddace` tool, or any shell command, from an end-to-end test: the one
// copy for every test binary of test/unit/. catkin builds the tool and the test binaries into the same
// directory (devel/lib/ddace), so the tool is found next to the running test binary.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

namespace ddace::test {

/// How a run of the tool ended.
struct ToolRun {
  int status = -1;  ///< exit status; -1 when it could not start or was killed by a signal
  std::string out;  ///< stdout and stderr together, in the order written
};

/// The ddace tool next to this test binary.
inline std::filesystem::path toolPath() {
  return std::filesystem::read_symlink("/proc/self/exe").parent_path() / "ddace";
}

/// Runs `command` through /bin/sh and waits for it: its stdout and stderr together.
inline ToolRun runShell(const std::string& command) {
  ToolRun r;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int status = ::pclose(p);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// Runs `ddace ARGS` through /bin/sh: `args` is shell text, so quote paths with spaces.
inline ToolRun runTool(const std::string& args) {
  return runShell("'" + toolPath().string() + "' " + args);
}

}  // namespace ddace::test
