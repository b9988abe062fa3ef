// A node serving a role dies mid-run (SIGKILL: no goodbye): the coordinator publishes zero
// wheels on every robot at once, aborts the run naming the node, and the monitor writes
// the report of the partial run. Ctrl-C (SIGINT) of a running launch also leaves a report.
#include "exec_common.h"

using namespace exec_test;

namespace {

bool anyDriving(Watcher& w) {
  for (const auto& [robot, cmds] : w.wheels())
    if (!cmds.empty() && (cmds.back().left != 0 || cmds.back().right != 0)) return true;
  return false;
}

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
  const ros::Time killed = ros::Time::now();
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 5.0))
      << "state " << w.state().state_name;
  ros::Duration(0.3).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find(node), std::string::npos) << s.reason;
  // Every robot got a zero command soon after the kill, and nothing but zeros since.
  double worst_s = 0;
  for (const auto& [robot, cmds] : w.wheels()) {
    ros::Time first_zero;
    for (const auto& c : cmds)
      if (c.stamp > killed && c.left == 0 && c.right == 0) {
        first_zero = c.stamp;
        break;
      }
    ASSERT_NE(first_zero, ros::Time()) << robot << " got no zero command after " << node << " died";
    worst_s = std::max(worst_s, (first_zero - killed).toSec());
    // The follower's command of the cycle under way may still cross the coordinator's zero
    // on the wire (two publishers); one cycle later everything is zero.
    for (const auto& c : cmds)
      if (c.stamp > first_zero + ros::Duration(0.05)) {
        EXPECT_TRUE(c.left == 0 && c.right == 0)
            << robot << " driven " << (c.stamp - first_zero).toSec() << " s after its first zero";
      }
    EXPECT_TRUE(cmds.back().left == 0 && cmds.back().right == 0) << robot;
  }
  // The robots were driving at 50 Hz: a zero for each within a few control cycles of the kill
  // (the coordinator checks its roles at 50 Hz and zeroes every robot on detection).
  EXPECT_LT(worst_s, 0.1) << "last robot stopped " << worst_s << " s after " << node << " was killed";
  std::cout << node << " killed: every robot at zero after " << worst_s << " s\n";
  ASSERT_TRUE(graph.waitExit(20.0)) << "the launch did not end after the abort";
  const std::string report = readFile(g.run_dir + "/report.txt");
  EXPECT_NE(report.find("aborted"), std::string::npos) << report;
  EXPECT_NE(report.find(node), std::string::npos) << report;
  EXPECT_NE(readFile(g.run_dir + "/result.json").find("\"aborted\""), std::string::npos);
}

INSTANTIATE_TEST_SUITE_P(Roles, KillRole, ::testing::Values("/path_follower", "/sequence", "/gp_path", "/mock_robots"),
                         [](const auto& info) { return info.param.substr(1); });

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
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_liveness_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
