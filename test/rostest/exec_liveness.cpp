// A node serving a role dies mid-run (SIGKILL: no goodbye): the coordinator publishes zero
// wheels on every robot at once, aborts the run naming the node, and the monitor writes
// the report of the partial run. Ctrl-C (SIGINT) of a running launch also leaves a report.
#include <ddace/PathRequest.h>

#include "exec_common.h"

using namespace exec_test;

namespace {

bool anyDriving(Watcher& w) {
  for (const auto& [robot, cmds] : w.wheels())
    if (!cmds.empty() && !cmds.back().zero()) return true;
  return false;
}

/// Sees a node's death the way the coordinator does: a topic the node subscribes to,
/// advertised here (never published), whose disconnect callback fires when the node's
/// link drops. `dropped()` is when that happened (ros::Time() before).
class DeathProbe {
 public:
  DeathProbe(ros::NodeHandle& nh, const std::string& node) : node_(node) {
    if (node == "/path_follower") pub_ = advertise<ddace::Segment>(nh, "/robots/R1/segment");
    if (node == "/sequence") pub_ = advertise<ddace::DecisionRequest>(nh, "/ddace/decision_request");
    if (node == "/gp_path") pub_ = advertise<ddace::PathRequest>(nh, "/ddace/path_request");
    if (node == "/mock_robots") pub_ = advertise<ddace::WheelCommand>(nh, "/robots/R1/wheels");
  }
  bool linked() {
    std::lock_guard<std::mutex> l(mu_);
    return linked_;
  }
  ros::Time dropped() {
    std::lock_guard<std::mutex> l(mu_);
    return dropped_;
  }

 private:
  template <typename M>
  ros::Publisher advertise(ros::NodeHandle& nh, const std::string& topic) {
    return nh.advertise<M>(
        topic, 1,
        [this](const ros::SingleSubscriberPublisher& p) {
          std::lock_guard<std::mutex> l(mu_);
          if (p.getSubscriberName() == node_) linked_ = true;
        },
        [this](const ros::SingleSubscriberPublisher& p) {
          const ros::Time now = ros::Time::now();
          std::lock_guard<std::mutex> l(mu_);
          if (p.getSubscriberName() == node_ && dropped_ == ros::Time()) dropped_ = now;
        });
  }
  std::string node_;
  ros::Publisher pub_;
  std::mutex mu_;
  bool linked_ = false;
  ros::Time dropped_;
};

std::string readFile(const std::string& path) {
  std::ifstream f(path);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

struct Graph {
  ros::NodeHandle nh;
  Files files = Files::fromParams();
  ScratchDir scratch{"liveness"};
  ddace::task::TaskDir test;
  std::string run_dir;

  explicit Graph(const std::string& name) {
    generateTask(scratch, "task4", 3, 1, 4);
    test = ddace::task::loadTaskDir(std::string(scratch) + "/test");
    run_dir = std::string(scratch) + "/run_" + name;
  }
  std::vector<std::string> args() const {
    return {files.launch_file,
            "task:=" + std::string(scratch) + "/test",
            "train:=" + std::string(scratch) + "/train",
            "autostart:=false",
            "monitor:=true",
            "run_dir:=" + run_dir,
            "config:=" + files.config_file};
  }
};

}  // namespace

class KillRole : public ::testing::TestWithParam<std::string> {};

TEST_P(KillRole, StopsEveryRobotAtOnceAndAbortsNamingTheNode) {
  const std::string node = GetParam();
  Graph g(node.substr(1));
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING && anyDriving(w); }, 20.0));
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode(node);
  ASSERT_GT(pid, 0) << "no pid for " << node;
  DeathProbe probe(g.nh, node);
  ASSERT_TRUE(waitFor([&] { return probe.linked(); }, 10.0)) << node << " did not subscribe to the probe";
  const ros::Time killed = ros::Time::now();
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 5.0))
      << "state " << w.state().state_name;
  ros::Duration(0.3).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find(node), std::string::npos) << s.reason;
  // Known through the link dropping, not a heartbeat time-out.
  EXPECT_NE(s.reason.find("is gone"), std::string::npos) << s.reason;
  const ros::Time knew = w.firstStamp(ddace::CoordinatorState::ABORTED);
  double worst_s = 0;
  for (const auto& [robot, cmds] : w.wheels()) {
    // The coordinator zeroes every robot itself in the callback that learns of the loss,
    // before it announces the abort ...
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), killed);
    ASSERT_NE(zero, ros::Time()) << "the coordinator sent " << robot << " no zero after " << node << " died";
    EXPECT_LE(zero, knew) << robot << ": zeroed after the abort was announced";
    worst_s = std::max(worst_s, (zero - killed).toSec());
    // ... and a living follower stops within its cycle under way: at most one more
    // command, then zeros. A dead follower sends nothing after the kill but zeros.
    if (node == "/path_follower") {
      for (const auto& c : cmds) {
        if (c.stamp > killed) {
          EXPECT_TRUE(c.zero()) << robot << " driven " << (c.stamp - killed).toSec() << " s after the kill";
        }
      }
    } else {
      EXPECT_TRUE(zeroWithinOneCycle(from(cmds, "/path_follower"), zero)) << robot;
    }
    EXPECT_TRUE(cmds.back().zero()) << robot;
  }
  // When the link dropped, as another process saw it: the rest is the coordinator's own part.
  ASSERT_TRUE(waitFor([&] { return probe.dropped() != ros::Time(); }, 2.0));
  if (node != "/path_follower") {
    // Counted in the living follower's control cycles: from the drop to the coordinator's
    // zero at most the one under way.
    const auto cmds = w.wheels()["R1"];
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), killed);
    int cycles = 0;
    for (const auto& c : from(cmds, "/path_follower"))
      if (c.stamp > probe.dropped() && c.stamp < zero) ++cycles;
    EXPECT_LE(cycles, 1) << "the coordinator zeroed R1 " << cycles << " control cycles after the link dropped";
  }
  std::cout << node << " killed: its link dropped " << (probe.dropped() - killed).toSec()
            << " s after the signal (seen by this test); every robot zeroed by the coordinator " << worst_s
            << " s after the signal\n";
  ASSERT_TRUE(graph.waitExit(20.0)) << "the launch did not end after the abort";
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("aborted"), std::string::npos) << report;
  EXPECT_NE(report.find(node), std::string::npos) << report;
  EXPECT_NE(readFile(g.run_dir + "/result.json").find("\"aborted\""), std::string::npos);
  EXPECT_EQ(checkRun(g.files, g.run_dir), 1) << "execute_sim --check must fail an aborted run";
}

INSTANTIATE_TEST_SUITE_P(Roles, KillRole, ::testing::Values("/path_follower", "/sequence", "/gp_path", "/mock_robots"),
                         [](const auto& info) { return info.param.substr(1); });

// A follower that hangs (SIGSTOP: its links stay up) is lost by its heartbeat: after
// heartbeat_timeout_s (0.5) without a wheel command the coordinator zeroes every robot in
// the check that finds it and aborts naming the node.
TEST(Hang, AFollowerThatHangsIsLostByItsHeartbeat) {
  Graph g("hang");
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING && anyDriving(w); }, 20.0));
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode("/path_follower");
  ASSERT_GT(pid, 0);
  const ros::Time hung = ros::Time::now();
  ASSERT_EQ(::kill(pid, SIGSTOP), 0);
  const bool aborted = waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 5.0);
  ::kill(pid, SIGCONT);
  ASSERT_TRUE(aborted) << "state " << w.state().state_name;
  const auto s = w.state();
  EXPECT_NE(s.reason.find("/path_follower"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("silent"), std::string::npos) << s.reason;
  const ros::Time knew = w.firstStamp(ddace::CoordinatorState::ABORTED);
  for (const auto& [robot, cmds] : w.wheels()) {
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), hung);
    ASSERT_NE(zero, ros::Time()) << robot;
    EXPECT_LE(zero, knew) << robot;
    // Not before the heartbeat time-out after the follower's last command.
    ros::Time last_beat;
    for (const auto& c : from(cmds, "/path_follower"))
      if (c.stamp < zero) last_beat = c.stamp;
    EXPECT_GE((zero - last_beat).toSec(), 0.5) << robot;
    if (robot == "R1")
      std::cout << "/path_follower hung: every robot zeroed by the coordinator " << (zero - hung).toSec()
                << " s later (heartbeat_timeout_s 0.5)\n";
  }
  ASSERT_TRUE(graph.waitExit(20.0)) << "the launch did not end after the abort";
  EXPECT_NE(readFile(g.run_dir + "/report.txt").find("silent"), std::string::npos);
}

TEST(Sigint, AnInterruptedRunLeavesItsReport) {
  Graph g("sigint");
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING && anyDriving(w); }, 20.0));
  graph.interrupt();
  ASSERT_TRUE(graph.waitExit(30.0));
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("interrupted"), std::string::npos) << report;
  EXPECT_NE(report.find("step 1:"), std::string::npos) << "the partial run's steps are in the report\n" << report;
  const std::string result = readFile(g.run_dir + "/result.json");
  EXPECT_NE(result.find("\"state\": \"interrupted\""), std::string::npos) << result;
  EXPECT_EQ(checkRun(g.files, g.run_dir), 1) << "execute_sim --check must fail an interrupted run";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_liveness_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
