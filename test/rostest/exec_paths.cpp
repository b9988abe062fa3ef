// Relative paths, as the README writes them (task:=out/task4/test): execute_sim.launch
// resolves task, train and model against the directory roslaunch was started in; a node,
// which runs in ROS_HOME, refuses a relative path with a message that says so.
#include <cstdio>
#include <string>
#include <vector>

#include "exec_common.h"

using namespace exec_test;

namespace {

/// Runs `command` in `dir` (sh -c); returns its exit status and fills `output` (stdout + stderr).
int run(const std::string& dir, const std::string& command, std::string& output) {
  FILE* p = ::popen(("cd '" + dir + "' && " + command + " 2>&1").c_str(), "r");
  if (!p) return -1;
  output.clear();
  char buf[4096];
  for (size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) output.append(buf, n);
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST(ExecPaths, TheLaunchFileResolvesRelativePathsAgainstTheCallersDirectory) {
  const Files files = Files::fromParams();
  const ScratchDir caller("paths_caller");
  std::string out;
  ASSERT_EQ(
      run(caller, "roslaunch --dump-params '" + files.launch_file + "' task:=out/task4/test model:=out/model", out), 0)
      << out;
  const YAML::Node params = YAML::Load(out);
  const std::string task = std::string(caller) + "/out/task4/test", model = std::string(caller) + "/out/model";
  for (const std::string node : {"coordinator", "mock_robots", "path_follower", "sequence", "execution_monitor"})
    EXPECT_EQ(params["/" + node + "/task"].as<std::string>(""), task) << node;
  EXPECT_EQ(params["/sequence/model"].as<std::string>(""), model);
  EXPECT_EQ(params["/gp_path/library"].as<std::string>(""), model);
}

// The real table's launch file the same way; it records the run too, and watches the node
// that really publishes the poses: the tracker, or as a nodelet its manager.
TEST(ExecPaths, TheRealLaunchFileResolvesPathsRecordsAndWatchesThePosePublisher) {
  std::string launch;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("real_launch_file", launch));
  const ScratchDir caller("paths_real");
  for (const bool nodelet : {false, true}) {
    std::string out;
    ASSERT_EQ(run(caller,
                  "roslaunch --dump-params '" + launch +
                      "' task:=out/task model:=out/model nodelet:=" + (nodelet ? "true" : "false"),
                  out),
              0)
        << out;
    const YAML::Node params = YAML::Load(out);
    EXPECT_EQ(params["/coordinator/task"].as<std::string>(""), std::string(caller) + "/out/task");
    EXPECT_EQ(params["/execution_monitor/task"].as<std::string>(""), std::string(caller) + "/out/task");
    // the tracker refuses a markers file without a marker for one of the task's entities
    EXPECT_EQ(params["/tracker/task"].as<std::string>(""), std::string(caller) + "/out/task");
    EXPECT_EQ(params["/sequence/model"].as<std::string>(""), std::string(caller) + "/out/model");
    EXPECT_EQ(params["/coordinator/roles/recorder"].as<std::string>(""), "/execution_monitor");
    EXPECT_EQ(params["/coordinator/roles/pose_source"].as<std::string>(""), nodelet ? "/camera_manager" : "/tracker");
  }
}

// Two simulated rehearsals at once: each run's mock Hamsters and bridge meet in a directory
// of pty links of their own, so the bridge of one never drives the mock robots of another
// (the mock refuses a directory another live run holds: test_hamster's LinkDirTest).
TEST(ExecPaths, EachSimulatedRunOfTheRealLaunchFileLinksItsMockRobotsInADirectoryOfItsOwn) {
  std::string launch;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("real_launch_file", launch));
  const ScratchDir caller("paths_links");
  std::vector<std::string> dirs;
  for (int run_index = 0; run_index < 2; ++run_index) {
    std::string out;
    ASSERT_EQ(run(caller, "roslaunch --dump-params '" + launch + "' task:=out/task model:=out/model sim:=true", out), 0)
        << out;
    const YAML::Node params = YAML::Load(out);
    dirs.push_back(params["/mock_hamster/link_dir"].as<std::string>(""));
    EXPECT_FALSE(dirs.back().empty()) << out;
    EXPECT_EQ(params["/hamster_bridge/mock_link_dir"].as<std::string>(""), dirs.back());
  }
  EXPECT_NE(dirs[0], dirs[1]);
}

TEST(ExecPaths, ANodeRefusesARelativeTaskPathSayingWhy) {
  const ScratchDir caller("paths_node");
  std::string out;
  const int status =
      run(caller, "rosrun ddace coordinator_node __name:=relative_task_check _task:=out/task4/test", out);
  EXPECT_EQ(status, 1) << out;
  EXPECT_NE(out.find("out/task4/test"), std::string::npos) << out;
  EXPECT_NE(out.find("relative path"), std::string::npos) << out;
  EXPECT_NE(out.find("ROS_HOME"), std::string::npos) << out;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_paths_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
