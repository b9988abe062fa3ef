// bench_cli_start: how long the `ddace` subcommands that need no model take to start and
// finish, against a trivial process (/bin/true) measured in the same run.
//
// The front end `ddace` does not load libtorch; the subcommands that learn or evaluate are
// in ddace_learn, which it runs for them (CMakeLists.txt). Measured, each run a child
// process (wall time from fork to wait4), the median of kRuns interleaved rounds:
//   /bin/true                                 the reference: starting any process
//   ddace help                                the front end
//   ddace validate DIR                        a task made by `ddace init` (nothing recorded)
//   ddace generate --help, and generate task1 --out DIR --train 1 --test 1 (start and work)
//   ddace label --help
//   ddace_learn help                          what every subcommand cost before the split
// Goal: help, validate, generate and label start (--help: parse, print, exit)
// under 0.1 s; validate of a new task included.
// Writes docs/bench/cli_start.md under the repository it finds at run time (--repo DIR, see bench/results.h).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/machine.h"
#include "peak_memory.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

constexpr int kRuns = 15;
constexpr double kGoalS = 0.1;

struct Case {
  std::string name;
  std::vector<std::string> argv;
  bool goal = false;  ///< held to kGoalS
  std::vector<double> seconds;
  int status = 0;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const fs::path repo = bench::repositoryFromArgs(argc, argv);
    bench::noOtherOptions(argc, argv, "bench_cli_start");
    const fs::path dir = fs::read_symlink("/proc/self/exe").parent_path();
    const std::string tool = (dir / "ddace").string(), learn = (dir / "ddace_learn").string();
    const fs::path scratch = fs::temp_directory_path() / ("ddace_cli_start_" + std::to_string(::getpid()));
    fs::remove_all(scratch);
    fs::create_directories(scratch);
    const std::string task = (scratch / "task").string(), generated = (scratch / "generated").string();
    if (bench::runChild({tool, "init", task, "--robots", "R1,R2", "--objects", "B1", "--goals", "G1"}).status != 0)
      throw Error("ddace init " + task + " failed");
    const std::string load = loadAverage();

    std::vector<Case> cases = {
        {"`/bin/true` (reference)", {"/bin/true"}, false, {}, 0},
        {"`ddace help`", {tool, "help"}, true, {}, 0},
        {"`ddace validate DIR` (a task from `ddace init`)", {tool, "validate", task}, true, {}, 0},
        {"`ddace generate --help`", {tool, "generate", "--help"}, true, {}, 0},
        {"`ddace generate task1 --out DIR --train 1 --test 1 --force` (start and its work)",
         {tool, "generate", "task1", "--out", generated, "--train", "1", "--test", "1", "--force"},
         false,
         {},
         0},
        {"`ddace label --help`", {tool, "label", "--help"}, true, {}, 0},
        {"`ddace_learn help` (libtorch loaded: every subcommand before the split)", {learn, "help"}, false, {}, 0},
    };
    for (int round = 0; round < kRuns; ++round)
      for (auto& c : cases) {
        const bench::ChildRun run = bench::runChild(c.argv, "/dev/null");
        c.seconds.push_back(run.seconds);
        if (run.status != 0) c.status = run.status;
      }
    fs::remove_all(scratch);

    const double reference = median(cases.front().seconds);
    std::ostringstream md;
    md << std::fixed << std::setprecision(3);
    md << "# Start-up time of the ddace tool\n\n"
       << "Written by `bench_cli_start` (bench/cli_start.cpp; `ddace bench cli_start`). Do not edit.\n\n"
       << "Each command is run " << kRuns << " times as a child process, the cases interleaved; the median "
       << "wall time from fork to exit. The reference, starting a trivial process, is measured in the same run. "
       << utcNow() << ", 1-minute load average at the start: " << load << ".\n\n"
       << "| command | median wall (s) | x reference | exit status |\n|---|---:|---:|---:|\n";
    bool met = true;
    for (const auto& c : cases) {
      const double m = median(c.seconds);
      md << "| " << c.name << " | " << m << " | " << std::setprecision(1) << m / std::max(reference, 1e-6)
         << std::setprecision(3) << " | " << c.status << " |\n";
      if (c.goal && (m >= kGoalS || c.status != 0)) met = false;
    }
    md << "\nGoal: `ddace help`, `validate`, `generate` and `label` under " << kGoalS
       << " s, without libtorch: " << (met ? "met" : "NOT met") << ".\n";
    bench::writeResults(repo, "cli_start", md.str());
    std::cout << md.str();
    return met ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "bench_cli_start: " << e.what() << "\n";
    return 2;
  }
}
