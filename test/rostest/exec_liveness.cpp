// A node serving a role dies mid-run (SIGKILL: no goodbye) or hangs (SIGSTOP): the
// coordinator publishes zero wheels on every robot, aborts the run naming the node, and the
// monitor writes the report of the partial run; the monitor (the recorder) is a role too.
// Ctrl-C (SIGINT) of a running launch also leaves a report, and so does an autostart that
// never could start (start_timeout_s).
#include <ddace/Heartbeat.h>
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

/// Task 4 with 4 robots, the run recorded into run_NAME.
struct Graph : TaskGraph {
  std::string run_dir;
  explicit Graph(const std::string& name) : TaskGraph("liveness", "task4", 3, 1, 4), run_dir(dir() + "/run_" + name) {}
  std::vector<std::string> args() const {
    return TaskGraph::args({"monitor:=true", "run_dir:=" + run_dir, "config:=" + files.config_file});
  }
};

/// Starts a run and waits until it is executing with some robot driving.
::testing::AssertionResult runUnderWay(Watcher& w) {
  const std::string started = startRun(w, 30.0);
  if (!started.empty()) return ::testing::AssertionFailure() << started;
  if (!waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING && anyDriving(w); }, 20.0))
    return ::testing::AssertionFailure() << "the run did not get under way (state " << w.state().state_name << ")";
  return ::testing::AssertionSuccess();
}

/// SIGKILLs `pid` (`killed`: the moment just before the signal) and waits for the run to
/// abort, then lets the last wheel commands and states arrive.
::testing::AssertionResult killAndAwaitAbort(Watcher& w, int pid, ros::Time& killed) {
  killed = ros::Time::now();
  if (::kill(pid, SIGKILL) != 0) return ::testing::AssertionFailure() << "cannot kill pid " << pid;
  if (!waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 5.0))
    return ::testing::AssertionFailure() << "no abort after the kill (state " << w.state().state_name << ")";
  ros::Duration(0.3).sleep();
  return ::testing::AssertionSuccess();
}

}  // namespace

class KillRole : public ::testing::TestWithParam<std::string> {};

TEST_P(KillRole, StopsEveryRobotAtOnceAndAbortsNamingTheNode) {
  const std::string node = GetParam();
  Graph g(node.substr(1));
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  ASSERT_TRUE(runUnderWay(w));
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode(node);
  ASSERT_GT(pid, 0) << "no pid for " << node;
  DeathProbe probe(g.nh, node);
  ASSERT_TRUE(waitFor([&] { return probe.linked(); }, 10.0)) << node << " did not subscribe to the probe";
  ros::Time killed;
  ASSERT_TRUE(killAndAwaitAbort(w, pid, killed));
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

namespace {

/// coordinator/roles/heartbeat_timeout_s of the config the graph runs with.
double heartbeatTimeout(const Files& files) {
  return YAML::LoadFile(files.config_file)["coordinator"]["roles"]["heartbeat_timeout_s"].as<double>();
}

/// The stamps of what `node` publishes as its heartbeat: the follower's wheel commands
/// (R1's), every other node's ~heartbeat.
class HeartbeatLog {
 public:
  HeartbeatLog(ros::NodeHandle& nh, const std::string& node) {
    if (node == "/path_follower") return;  // its wheels: the Watcher has them
    sub_ = nh.subscribe<ddace::Heartbeat>(node + "/heartbeat", 50, [this](const ddace::Heartbeat::ConstPtr& m) {
      std::lock_guard<std::mutex> l(mu_);
      stamps_.push_back(m->header.stamp);
    });
  }
  bool heard() {
    std::lock_guard<std::mutex> l(mu_);
    return !sub_ || !stamps_.empty();
  }
  /// The last heartbeat stamped before `t` (ros::Time() when none).
  ros::Time lastBefore(const ros::Time& t) {
    std::lock_guard<std::mutex> l(mu_);
    ros::Time last;
    for (const auto& s : stamps_)
      if (s < t) last = s;
    return last;
  }

 private:
  // Declared before the subscription, so they outlive it: its callback may still run while
  // the log is destroyed, and the subscription's destructor waits for it.
  std::mutex mu_;
  std::vector<ros::Time> stamps_;
  ros::Subscriber sub_;
};

}  // namespace

// A node that hangs (SIGSTOP: its links stay up, it answers nothing) is lost by its
// heartbeat: heartbeat_timeout_s after its last one the coordinator zeroes every robot in
// the check that finds it, then aborts naming the node (the follower's heartbeat is its
// wheel stream; the sequence and path nodes publish ~heartbeat).
class HangRole : public ::testing::TestWithParam<std::string> {};

TEST_P(HangRole, IsLostByItsHeartbeatAndEveryRobotStops) {
  const std::string node = GetParam();
  Graph g("hang_" + node.substr(1));
  const double timeout_s = heartbeatTimeout(g.files);
  Watcher w(g.nh, g.test.spec);
  HeartbeatLog beats(g.nh, node);
  Launch graph(g.args());
  ASSERT_TRUE(runUnderWay(w));
  ASSERT_TRUE(waitFor([&] { return beats.heard(); }, 5.0)) << "no heartbeat of " << node;
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode(node);
  ASSERT_GT(pid, 0);
  const ros::Time hung = ros::Time::now();
  ASSERT_EQ(::kill(pid, SIGSTOP), 0);
  const bool aborted = waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 5.0 + timeout_s);
  ::kill(pid, SIGCONT);
  ASSERT_TRUE(aborted) << "state " << w.state().state_name << " " << timeout_s + 5.0 << " s after " << node << " hung";
  ros::Duration(0.3).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find(node), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("silent"), std::string::npos) << s.reason;
  const ros::Time knew = w.firstStamp(ddace::CoordinatorState::ABORTED);
  for (const auto& [robot, cmds] : w.wheels()) {
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), hung);
    ASSERT_NE(zero, ros::Time()) << robot;
    EXPECT_LE(zero, knew) << robot << ": zeroed after the abort was announced";
    // Not before the heartbeat time-out after the node's last heartbeat, less one beat: the
    // node's last message may have reached this test but not the coordinator (each link is
    // written on its own; the signal can stop the node between the two writes).
    ros::Time last_beat;
    const YAML::Node config = YAML::LoadFile(g.files.config_file);
    double beat_s = 0;
    if (node == "/path_follower") {
      beat_s = 1.0 / config["path_follower"]["rate_hz"].as<double>();  // its control cycle
      for (const auto& c : from(cmds, "/path_follower"))
        if (c.stamp < zero) last_beat = c.stamp;
    } else {
      beat_s = 1.0 / config[node.substr(1)]["heartbeat_rate_hz"].as<double>();
      last_beat = beats.lastBefore(zero);
      // A living follower stops within its control cycle under way.
      EXPECT_TRUE(zeroWithinOneCycle(from(cmds, "/path_follower"), zero)) << robot;
    }
    ASSERT_NE(last_beat, ros::Time()) << robot;
    EXPECT_GE((zero - last_beat).toSec(), timeout_s - beat_s) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot;
    if (robot == "R1")
      std::cout << node << " hung: every robot zeroed by the coordinator " << (zero - hung).toSec()
                << " s after the signal, " << (zero - last_beat).toSec() << " s after its last heartbeat"
                << " (heartbeat_timeout_s " << timeout_s << ")\n";
  }
  ASSERT_TRUE(graph.waitExit(20.0)) << "the launch did not end after the abort";
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("silent"), std::string::npos) << report;
  EXPECT_NE(report.find(node), std::string::npos) << report;
}

INSTANTIATE_TEST_SUITE_P(Roles, HangRole, ::testing::Values("/path_follower", "/sequence", "/gp_path"),
                         [](const auto& info) { return info.param.substr(1); });

// The recorder is a role: a run without its record does not go on. The monitor killed
// mid-run (its link on /coordinator/state drops): every robot stops, the run aborts naming
// it, and its rosbag child, told by the kernel (SIGINT on its parent's death), closes the
// bag of the run so far.
TEST(Recorder, AKilledMonitorStopsTheRunAndItsBagIsClosed) {
  Graph g("monitor");
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  ASSERT_TRUE(runUnderWay(w));
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode("/execution_monitor");
  ASSERT_GT(pid, 0);
  ros::Time killed;
  ASSERT_TRUE(killAndAwaitAbort(w, pid, killed));
  const auto s = w.state();
  EXPECT_NE(s.reason.find("/execution_monitor is gone"), std::string::npos) << s.reason;
  const ros::Time knew = w.firstStamp(ddace::CoordinatorState::ABORTED);
  double worst_s = 0;
  for (const auto& [robot, cmds] : w.wheels()) {
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), killed);
    ASSERT_NE(zero, ros::Time()) << robot;
    EXPECT_LE(zero, knew) << robot;
    // The follower stops when the STOP reaches it. Here that can take a cycle more than
    // elsewhere: the monitor's death makes rosbag close its bag at that very moment (a
    // burst of work that delayed the STOP to one robot by a cycle in 1 of 4 runs).
    EXPECT_TRUE(zeroWithinCycles(from(cmds, "/path_follower"), zero, 3)) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot;
    worst_s = std::max(worst_s, (zero - killed).toSec());
  }
  std::cout << "/execution_monitor killed: every robot zeroed by the coordinator " << worst_s
            << " s after the signal\n";
  const std::string bag = g.run_dir + "/run.bag";
  ASSERT_TRUE(waitFor([&] { return fs::exists(bag) && !fs::exists(bag + ".active"); }, 15.0))
      << "rosbag record did not close " << bag;
  EXPECT_EQ(std::system(("rosbag info '" + bag + "' > /dev/null 2>&1").c_str()), 0) << bag;
}

// rosbag record dies mid-run: the monitor's heartbeat says so, the coordinator stops every
// robot and aborts naming the monitor and the problem, and the monitor records that run.
TEST(Recorder, ADeadBagStopsTheRunAndTheReportSaysWhy) {
  Graph g("bag");
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  ASSERT_TRUE(runUnderWay(w));
  ros::Duration(0.5).sleep();
  const int pid = pidOfNode("/execution_monitor_bag");
  ASSERT_GT(pid, 0) << "no rosbag record node /execution_monitor_bag";
  ros::Time killed;
  ASSERT_TRUE(killAndAwaitAbort(w, pid, killed));
  const auto s = w.state();
  EXPECT_NE(s.reason.find("/execution_monitor reports: rosbag record exited"), std::string::npos) << s.reason;
  for (const auto& [robot, cmds] : w.wheels()) {
    ASSERT_NE(firstZeroAfter(from(cmds, "/coordinator"), killed), ros::Time()) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot;
  }
  ASSERT_TRUE(graph.waitExit(20.0)) << "the launch did not end after the abort";
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("rosbag record exited"), std::string::npos) << report;
  EXPECT_NE(readFile(g.run_dir + "/result.json").find("\"aborted\""), std::string::npos);
}

TEST(Sigint, AnInterruptedRunLeavesItsReport) {
  Graph g("sigint");
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args());
  ASSERT_TRUE(runUnderWay(w));
  graph.interrupt();
  ASSERT_TRUE(graph.waitExit(30.0));
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("interrupted"), std::string::npos) << report;
  EXPECT_NE(report.find("step 1:"), std::string::npos) << "the partial run's steps are in the report\n" << report;
  const std::string result = readFile(g.run_dir + "/result.json");
  EXPECT_NE(result.find("\"state\": \"interrupted\""), std::string::npos) << result;
  EXPECT_EQ(checkRun(g.files, g.run_dir), 1) << "execute_sim --check must fail an interrupted run";
}

TEST(Autostart, ANodeMissingAtStartupAbortsAndEndsTheLaunchWithAReport) {
  // The sequence role names a node that never comes up (as if it died at startup): without
  // start_timeout_s the launch would wait for it for ever.
  Graph g("no_sequence");
  const std::string config =
      writeConfig(g.files.config_file, std::string(g.scratch) + "/execution.yaml",
                  {{{"coordinator", "start_timeout_s", "3.0"}},
                   {{"coordinator", "roles",
                     "{sequence: /no_such_sequence, paths: /gp_path, follower: /path_follower, driver: /mock_robots,"
                     " object_executor: /mock_robots, pose_source: /mock_robots, heartbeat_timeout_s: 1.0,"
                     " pose_timeout_s: 1.0}"}}});
  std::vector<std::string> args = g.args();
  for (auto& a : args) {
    if (a == "autostart:=false") a = "autostart:=true";
    if (a.rfind("config:=", 0) == 0) a = "config:=" + config;
  }
  Watcher w(g.nh, g.test.spec);
  Launch graph(args);
  ASSERT_TRUE(graph.waitExit(60.0)) << "the launch did not end after start_timeout_s";
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("start_timeout_s"), std::string::npos) << report;
  EXPECT_NE(report.find("/no_such_sequence"), std::string::npos) << "the report names the missing node\n" << report;
  EXPECT_EQ(checkRun(g.files, g.run_dir), 1) << "execute_sim --check must fail a run that never started";
  for (const auto& [robot, cmds] : w.wheels())
    for (const auto& c : cmds) EXPECT_TRUE(c.zero()) << robot << " was driven although nothing started";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_liveness_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
