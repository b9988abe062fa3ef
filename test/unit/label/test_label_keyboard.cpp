// scripts/label_keyboard.py --review (the reviewer of inferred labels) driven by scripted
// keys instead of a person: it reads its keys from a terminal, so it runs on a
// pseudo-terminal here. The corrected tokens must be written on exactly their rows, the
// accepted ones as they were, and the file must still be a valid demonstration.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "ddace/common/repository.h"
#include "ddace/task/task_dir.h"
#include "ddace/tasks/generators.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

struct TerminalRun {
  std::string output;
  int status = -1;
  bool killed = false;
};

/// Runs `argv` on a new pseudo-terminal (its controlling terminal and stdin/stdout/stderr);
/// types `keys` once `ready` appeared in its output, then reads until it exits. A run that
/// has not ended after `limit` is killed (a hang must fail the test, not stall the suite).
TerminalRun runOnTerminal(const std::vector<std::string>& argv, const std::string& ready, const std::string& keys,
                          std::chrono::seconds limit = std::chrono::seconds(30)) {
  TerminalRun run;
  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0) {
    ADD_FAILURE() << "no pseudo-terminal";
    return run;
  }
  const std::string slave_name = ptsname(master);
  const pid_t pid = fork();
  if (pid == 0) {
    setsid();
    const int slave = open(slave_name.c_str(), O_RDWR);  // the new session's controlling terminal
    dup2(slave, 0), dup2(slave, 1), dup2(slave, 2);
    close(master);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + limit;
  bool typed = false;
  char buf[4096];
  while (std::chrono::steady_clock::now() < deadline) {
    pollfd p{master, POLLIN, 0};
    if (poll(&p, 1, 100) > 0) {
      const ssize_t n = read(master, buf, sizeof buf);
      if (n <= 0) break;  // EIO: the program ended and closed the terminal
      run.output.append(buf, static_cast<size_t>(n));
    }
    // Typed only once it waits for keys: switching the terminal to cbreak mode drops
    // whatever was typed before.
    if (!typed && run.output.find(ready) != std::string::npos) {
      EXPECT_EQ(write(master, keys.data(), keys.size()), static_cast<ssize_t>(keys.size()));
      typed = true;
    }
  }
  // The terminal closes as the program exits, a moment before it can be waited for.
  pid_t done = 0;
  while ((done = waitpid(pid, &run.status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline) usleep(10000);
  if (done == 0) {
    kill(pid, SIGKILL);
    waitpid(pid, &run.status, 0);
    run.killed = true;
  }
  close(master);
  return run;
}

/// A token as the reviewer sees it: a run of rows in which an entity's label stays the
/// same and is not idle; ordered by first row, then entity.
struct LabelRun {
  int entity, first, last;
};

std::vector<LabelRun> runsOf(const task::Demonstration& d) {
  std::vector<LabelRun> runs;
  for (size_t e = 0; e < d.entities(); ++e) {
    if (!d.has_label_columns[e]) continue;
    for (size_t i = 0; i < d.rows(); ++i) {
      const task::Label& l = d.labels[i][e];
      if (l.isNull()) continue;
      if (i > 0 && !runs.empty() && runs.back().entity == static_cast<int>(e) &&
          runs.back().last == static_cast<int>(i) - 1 && d.labels[i - 1][e] == l)
        runs.back().last = static_cast<int>(i);
      else runs.push_back({static_cast<int>(e), static_cast<int>(i), static_cast<int>(i)});
    }
  }
  std::stable_sort(runs.begin(), runs.end(), [](const LabelRun& a, const LabelRun& b) {
    return a.first != b.first ? a.first < b.first : a.entity < b.entity;
  });
  return runs;
}

}  // namespace

TEST(LabelKeyboard, ReviewWritesTheCorrectionsAndKeepsTheAcceptedTokens) {
  const fs::path repo = findRepository("", {"scripts/label_keyboard.py"});
  tasks::GeneratorOptions o;
  o.family = "task1";  // four actions: drive, fly, transfer, stop
  o.demos = 1;
  const task::TaskDir truth = tasks::generate(o);
  const std::string dir = ::testing::TempDir() + "/ddace_label_keyboard_" + std::to_string(::getpid());
  fs::remove_all(dir);
  task::writeTaskDir(truth, dir);
  const std::string file = task::demoFiles(dir).at(0);
  const task::Demonstration before = task::readDemonstrationCsv(file, truth.spec);
  const std::vector<LabelRun> runs = runsOf(before);
  ASSERT_GE(runs.size(), 4u);

  // Token 1: next action; token 2: accepted; token 3: next target; token 4: dropped;
  // write, leave.
  const TerminalRun run = runOnTerminal(
      {"/usr/bin/python3", (repo / "scripts/label_keyboard.py").string(), "--review", file}, "token 1/", "anntnxwq");
  ASSERT_FALSE(run.killed) << run.output;
  ASSERT_TRUE(WIFEXITED(run.status) && WEXITSTATUS(run.status) == 0) << run.output;
  EXPECT_NE(run.output.find("wrote " + file), std::string::npos) << run.output;

  const task::Demonstration after = task::readDemonstrationCsv(file, truth.spec);  // still valid
  ASSERT_EQ(after.rows(), before.rows());
  const auto& actions = truth.spec.actions;
  const auto nextAction = [&](const std::string& a) {
    const auto it = std::find(actions.begin(), actions.end(), a);
    return actions[it == actions.end() ? 0 : (it - actions.begin() + 1) % actions.size()];
  };
  const auto nextTarget = [&](int entity, int target) {
    // None first, then every entity but the token's own, in task order.
    std::vector<int> options = {-1};
    for (int e = 0; e < static_cast<int>(truth.spec.entities.size()); ++e)
      if (e != entity) options.push_back(e);
    const auto it = std::find(options.begin(), options.end(), target);
    return options[(it - options.begin() + 1) % options.size()];
  };
  std::vector<std::vector<task::Label>> expected = before.labels;
  for (int i = runs[0].first; i <= runs[0].last; ++i)
    expected[i][runs[0].entity].action = nextAction(before.labels[i][runs[0].entity].action);
  for (int i = runs[2].first; i <= runs[2].last; ++i)
    expected[i][runs[2].entity].target = nextTarget(runs[2].entity, before.labels[i][runs[2].entity].target);
  for (int i = runs[3].first; i <= runs[3].last; ++i) expected[i][runs[3].entity] = task::Label{};
  int changed = 0;
  for (size_t i = 0; i < before.rows(); ++i)
    for (size_t e = 0; e < before.entities(); ++e) {
      EXPECT_EQ(after.labels[i][e].action, expected[i][e].action) << "row " << i << " entity " << e;
      EXPECT_EQ(after.labels[i][e].target, expected[i][e].target) << "row " << i << " entity " << e;
      EXPECT_EQ(after.positions[i][e], before.positions[i][e]);
      changed += !(before.labels[i][e] == after.labels[i][e]);
    }
  EXPECT_EQ(changed, (runs[0].last - runs[0].first + 1) + (runs[2].last - runs[2].first + 1) +
                         (runs[3].last - runs[3].first + 1));
  fs::remove_all(dir);
}
