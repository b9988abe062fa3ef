// A required node that dies at start ends the graph, and roslaunch exits 0 all the same.
// The commands a user runs, scripts/execute_sim and scripts/launch (the README's), must
// exit non-zero within seconds, naming the node, that it was required, and its cause. The
// node here is the coordinator, given a model whose manifest.yaml does not parse: it dies
// in its constructor (the sequence and gp_path nodes too), whatever the load, and needs no
// training.
#include "exec_common.h"

#include <netinet/in.h>
#include <sys/socket.h>

#include <cstdlib>

using namespace exec_test;

namespace {

/// Task 4 with 4 robots and a "model" whose manifest.yaml breaks at line 3, column 1.
struct Setup {
  ScratchDir scratch{"dead_node"};
  std::string task, model, scripts;
  Setup() {
    task = std::string(scratch) + "/task4";
    generateTask(task, "task4", 2, 1, 4);
    model = std::string(scratch) + "/model";
    fs::create_directories(model);
    std::ofstream(model + "/manifest.yaml") << "format: [\n  {key: x\n";
    std::ofstream(model + "/primitives.yaml") << "primitives: []\n";
    ros::NodeHandle("~").getParam("scripts", scripts);
  }
};

const Setup& setup() {
  static const Setup s;
  return s;
}

/// A TCP port the kernel has free now (a random one may be held by another graph's node,
/// and roslaunch then ends at once with no node dead).
int freePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  socklen_t size = sizeof address;
  const bool bound = fd >= 0 && bind(fd, reinterpret_cast<sockaddr*>(&address), size) == 0 &&
                     getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) == 0;
  if (fd >= 0) close(fd);
  EXPECT_TRUE(bound) << "no free TCP port";
  return bound ? ntohs(address.sin_port) : 11311;
}

/// Runs `command` (shell text) with a master port of its own; its status and output.
std::pair<int, std::string> run(const std::string& command, const std::string& out) {
  const int port = freePort();
  // `timeout` only keeps a hang from blocking the suite.
  const int status = std::system(("ROS_MASTER_URI=http://localhost:" + std::to_string(port) + " timeout -s INT 180 " +
                                  command + " > '" + out + "' 2>&1")
                                     .c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, readFile(out)};
}

/// The coordinator's own error: which file, where, and what.
std::string coordinatorCause() {
  return "/coordinator: " + setup().model + "/manifest.yaml:3:1: YAML syntax error";
}

/// The run record in `run_dir` says the run failed because the coordinator died, with its
/// cause, on the report's first line (not the SIGINT that ended the launch; which of the
/// nodes given the broken model died first varies), and in result.json; the first line.
std::string expectTheRecordNamesTheDeadCoordinator(const std::string& run_dir) {
  const std::string report = readFile(run_dir + "/report.txt");
  EXPECT_NE(report.find("node coordinator died (exit code 1), a required node"), std::string::npos) << report;
  EXPECT_NE(report.find(coordinatorCause()), std::string::npos) << report;
  const std::string first = report.substr(0, report.find('\n'));
  EXPECT_EQ(first.rfind("failed: node /", 0), 0u) << report;
  EXPECT_NE(first.find("before the coordinator reported any state: "), std::string::npos) << report;
  // The coordinator's own cause follows its death on that line, whether it died first
  // ("... a required node before ...: CAUSE") or after another ("; also ... a required node: CAUSE").
  const std::string coordinator_died = "node /coordinator died (exit code 1), a required node";
  const size_t at = first.find(coordinator_died);
  EXPECT_NE(at, std::string::npos) << report;
  if (at != std::string::npos) {
    const std::string cause = setup().model + "/manifest.yaml:3:1: YAML syntax error";
    const size_t colon = first.find(": ", at + coordinator_died.size());
    EXPECT_TRUE(colon != std::string::npos && first.compare(colon + 2, cause.size(), cause) == 0) << report;
  }
  EXPECT_EQ(first.find("SIGINT"), std::string::npos) << report;
  const std::string result = readFile(run_dir + "/result.json");
  EXPECT_NE(result.find("\"state\": \"failed\""), std::string::npos) << result;
  EXPECT_NE(result.find("\"node\": \"/coordinator\""), std::string::npos) << result;
  return first;
}

}  // namespace

TEST(DeadNode, ExecuteSimExitsNonZeroNamingTheDeadRequiredNodeAndItsCause) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string run_dir = std::string(setup().scratch) + "/execute_sim_run";
  const auto [status, printed] = run("'" + setup().scripts + "/execute_sim' '" + setup().task + "' --model '" +
                                         setup().model + "' --no-build --run-dir '" + run_dir + "'",
                                     std::string(setup().scratch) + "/execute_sim.out");
  EXPECT_EQ(status, 1) << printed;
  EXPECT_NE(printed.find("node coordinator died (exit code 1), a required node"), std::string::npos) << printed;
  EXPECT_NE(printed.find(coordinatorCause()), std::string::npos) << printed;
  const std::string first = expectTheRecordNamesTheDeadCoordinator(run_dir);
  EXPECT_NE(printed.find(first), std::string::npos) << "the first line is not on the terminal:\n" << printed;
  EXPECT_NE(std::system(("'" + setup().scripts + "/execute_sim' --check '" + run_dir + "' > /dev/null").c_str()), 0)
      << "execute_sim --check passed a run whose node died";
}

TEST(DeadNode, TheLaunchCommandExitsNonZeroWhereRoslaunchExitsZero) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string& t = setup().task;
  const std::string run_dir = std::string(setup().scratch) + "/launch_run";
  const auto [status, printed] =
      run("'" + setup().scripts + "/launch' execute_sim.launch task:='" + t + "/test' train:='" + t +
              "/train' model:='" + setup().model + "' run_dir:='" + run_dir + "'",
          std::string(setup().scratch) + "/launch.out");
  EXPECT_EQ(status, 1) << printed;
  EXPECT_NE(printed.find("launch: execute_sim.launch ended with a node dead (roslaunch's exit status: 0)"),
            std::string::npos)
      << printed;
  EXPECT_NE(printed.find("launch: node coordinator died (exit code 1), a required node"), std::string::npos) << printed;
  EXPECT_NE(printed.find(coordinatorCause()), std::string::npos) << printed;
  // The run's own record says so too, first, as execute_sim's does.
  const std::string first = expectTheRecordNamesTheDeadCoordinator(run_dir);
  EXPECT_NE(printed.find("launch: the run's report (" + run_dir + "/report.txt) begins: " + first), std::string::npos)
      << printed;
}

// A task without a demonstration (as `ddace init` leaves it) has no start scene: execute_sim
// says so before it starts a graph whose every node would die on it.
TEST(DeadNode, ExecuteSimOnATaskWithoutDemonstrationsSaysSoAtOnce) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string task = std::string(setup().scratch) + "/no_demos";
  fs::create_directories(task + "/demos");
  fs::copy_file(setup().task + "/test/task.yaml", task + "/task.yaml");
  const auto [status, printed] = run("'" + setup().scripts + "/execute_sim' '" + task + "' --no-build",
                                     std::string(setup().scratch) + "/no_demos.out");
  EXPECT_EQ(status, 2) << printed;
  EXPECT_NE(printed.find(task + "/demos has no demonstration"), std::string::npos) << printed;
  EXPECT_EQ(printed.find("on mock robots"), std::string::npos) << "a graph was started:\n" << printed;
}

// The counterpart: a run that finishes exits 0 naming no node, and its launch.log holds no
// error of the launch's own making (once every one carried "[rospack] Error: no such package
// media_export").
TEST(DeadNode, AFinishedRunExitsZeroAndItsLogNamesNoDeathAndNoError) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string run_dir = std::string(setup().scratch) + "/finished_run";
  const auto [status, printed] =
      run("'" + setup().scripts + "/execute_sim' '" + setup().task + "' --no-build --run-dir '" + run_dir + "'",
          std::string(setup().scratch) + "/finished.out");
  EXPECT_EQ(status, 0) << printed;
  EXPECT_NE(printed.find("result: finished"), std::string::npos) << printed;
  EXPECT_EQ(printed.find(" died"), std::string::npos) << printed;
  const std::string log = readFile(run_dir + "/launch.log");
  EXPECT_NE(log, "") << "no launch.log in " << run_dir;
  for (const char* error : {"[rospack] Error", "process has died", "[FATAL]"})
    EXPECT_EQ(log.find(error), std::string::npos) << "'" << error << "' in launch.log:\n" << log;
}

// The README's demonstration step on a machine without that camera: the tracker cannot open
// it and dies, ending the launch; scripts/launch names it, and the tracker's error says
// how to record anyway (another device, a recording, the simulated table).
TEST(DeadNode, RecordingWithoutTheCameraEndsNamingTheTrackerAndTheWaysAround) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string demos = std::string(setup().scratch) + "/demos";
  const auto [status, printed] = run("'" + setup().scripts +
                                         "/launch' record.launch video_device:=99 keyboard:=false rviz:=false "
                                         "output_dir:='" +
                                         demos + "'",
                                     std::string(setup().scratch) + "/record.out");
  EXPECT_EQ(status, 1) << printed;
  EXPECT_NE(printed.find("launch: node tracker died (exit code 1), a required node"), std::string::npos) << printed;
  for (const char* hint : {"cannot open V4L2 device /dev/video99", "video_device:=N", "video_file:=FILE",
                           "sim:=true rehearses on a simulated table"})
    EXPECT_NE(printed.find(hint), std::string::npos) << "'" << hint << "' not said:\n" << printed;
}

// The README's demonstration step on a machine without the program that opens the keyboard
// window (xterm): roslaunch refuses the launch blaming "a bad launch-prefix"; scripts/launch
// names the program and the way around (no windows, the tools from other terminals).
TEST(ScriptsLaunch, AWindowProgramNotInstalledIsNamedWithTheWayAround) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string demos = std::string(setup().scratch) + "/no_window";
  const auto [status, printed] = run("'" + setup().scripts +
                                         "/launch' record.launch video_device:=-1 rviz:=false "
                                         "'keyboard_prefix:=ddace-no-such-terminal -e' output_dir:='" +
                                         demos + "'",
                                     std::string(setup().scratch) + "/no_window.out");
  EXPECT_EQ(status, 1) << printed;
  for (const char* said : {"launch: ddace-no-such-terminal is not installed", "apt install ddace-no-such-terminal",
                           "keyboard:=false teleop:=false"})
    EXPECT_NE(printed.find(said), std::string::npos) << "'" << said << "' not said:\n" << printed;
}

// What the nodes say shows while the launch runs (the recorder's state after each
// demonstration, a node's error), not when it ends: scripts/launch passes their output
// through tee, a pipe, where unflushed lines would wait. Ended as Ctrl-C ends it: SIGINT to
// its process group.
TEST(ScriptsLaunch, TheNodesLinesShowWhileTheLaunchRuns) {
  ASSERT_FALSE(setup().scripts.empty()) << "the .test file must set ~scripts";
  const std::string dir = std::string(setup().scratch) + "/live", log = dir + "/launch.log";
  fs::create_directories(dir);
  const int port = freePort();
  const std::string command = "ROS_MASTER_URI=http://localhost:" + std::to_string(port) + " exec '" + setup().scripts +
                              "/launch' --log '" + log +
                              "' record.launch video_device:=-1 keyboard:=false rviz:=false output_dir:='" + dir +
                              "/demos' > '" + dir + "/out' 2>&1";
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setsid();
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  // The recorder waits for poses (the tracker for images): it says it is ready and stays up.
  const bool shown = waitFor([&] { return readFile(log).find("recorder_node: ready: ") != std::string::npos; }, 90.0);
  kill(-pid, SIGINT);
  int status = 0;
  const bool ended = waitFor([&] { return waitpid(pid, &status, WNOHANG) == pid; }, 60.0);
  if (!ended) {
    kill(-pid, SIGKILL);
    waitpid(pid, &status, 0);
  }
  EXPECT_TRUE(shown) << "the recorder's 'ready' line was not in the launch's output while it ran:\n" << readFile(log);
  EXPECT_TRUE(ended) << "the launch did not end on SIGINT within 60 s";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_dead_node_test");
  return RUN_ALL_TESTS();
}
