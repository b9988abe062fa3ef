// Nodes started with one mistyped parameter, or one that is not theirs, must exit
// non-zero with an error naming the parameter, never run on its default (src/ros/params.h). Each node is started with
// rosrun against rostest's master; `timeout` turns a node that keeps running into a failure.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <ros/ros.h>

namespace {

struct NodeRun {
  int status = -1;  ///< exit status of the node (124: still running after the time-out)
  std::string output;
};

NodeRun runNode(const std::string& node, const std::string& args, int timeout_s = 30) {
  const std::string cmd = "timeout " + std::to_string(timeout_s) + " rosrun ddace " + node + " " + args + " 2>&1";
  NodeRun r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[512];
  while (std::fgets(buf, sizeof buf, p)) r.output += buf;
  const int s = ::pclose(p);
  r.status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  return r;
}

const std::string kPkg = "$(rospack find ddace)";

}  // namespace

TEST(ParamsMistyped, SyntheticCameraRateHz) {
  const NodeRun r =
      runNode("synthetic_camera_node", "__name:=params_camera _markers_file:=" + kPkg +
                                           "/config/markers.yaml _camera_file:=" + kPkg +
                                           "/test/data/vision/synthetic_camera_clear.yaml _rate_hz:=fast");
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.status, 124) << "the node ran on the default: " << r.output;
  EXPECT_NE(r.output.find("parameter '/params_camera/rate_hz' has the wrong type (expected a number)"),
            std::string::npos)
      << r.output;
}

TEST(ParamsMistyped, HamsterBridgePortDir) {
  const NodeRun r = runNode("hamster_bridge_node", "__name:=params_bridge _config:=" + kPkg +
                                                       "/test/rostest/hamster_bridge.yaml _port_dir:=42");
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.status, 124) << "the node ran on the default: " << r.output;
  EXPECT_NE(r.output.find("parameter '/params_bridge/port_dir' has the wrong type (expected a string)"),
            std::string::npos)
      << r.output;
}

TEST(ParamsMistyped, MockHamsterRobotTimeout) {
  char tmpl[] = "/tmp/ddace_params_mistyped_XXXXXX";
  ASSERT_NE(::mkdtemp(tmpl), nullptr);
  const NodeRun r = runNode("mock_hamster_node", "__name:=params_mock _config:=" + kPkg +
                                                     "/test/rostest/hamster_bridge.yaml _link_dir:=" + tmpl +
                                                     " _robot_timeout_s:=soon");
  std::filesystem::remove_all(tmpl);
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.status, 124) << "the node ran on the default: " << r.output;
  EXPECT_NE(r.output.find("parameter '/params_mock/robot_timeout_s' has the wrong type (expected a number)"),
            std::string::npos)
      << r.output;
}

// A misspelt parameter ("rate_hzz") is not the node's: it stops the node, naming it, and
// the node's own parameters (a follower left on its 50 Hz would drive at another rate
// than the launch file asks).
TEST(ParamsUnknown, AMisspeltOneStopsTheNode) {
  const NodeRun r =
      runNode("path_follower_node", "__name:=params_follower _task:=" + kPkg + "/test/data/exec/carry _rate_hzz:=20");
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.status, 124) << "the node ran on the default: " << r.output;
  EXPECT_NE(r.output.find("parameter /params_follower/rate_hzz is not one of node /params_follower's"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("rate_hz, robots"), std::string::npos) << "its own listed: " << r.output;
}

// ... while every parameter the node reads, nested ones included, is known: it runs.
TEST(ParamsUnknown, TheNodesOwnAreKnown) {
  const NodeRun r = runNode("path_follower_node",
                            "__name:=params_follower_own _task:=" + kPkg +
                                "/test/data/exec/carry _rate_hz:=20 _gains/lookahead_m:=0.05 _safety/enabled:=false",
                            5);
  EXPECT_EQ(r.status, 124) << "the node should still be running when the time-out ends it: " << r.output;
}

// The Python nodes check their namespace as the C++ ones: the calibration tool would run
// its default speeds, the keyboard its default recorder.
TEST(ParamsUnknown, APythonNodeStopsToo) {
  const NodeRun calibrate = runNode("calibrate_hamster.py", "__name:=params_calibrate _robot:=R1 _speedz:=[0.05]");
  EXPECT_NE(calibrate.status, 0) << calibrate.output;
  EXPECT_NE(calibrate.status, 124) << "the node ran on the default: " << calibrate.output;
  EXPECT_NE(calibrate.output.find("parameter /params_calibrate/speedz is not one of node /params_calibrate's"),
            std::string::npos)
      << calibrate.output;
  EXPECT_NE(calibrate.output.find("robot, config, speeds"), std::string::npos) << calibrate.output;
  const NodeRun keyboard = runNode("label_keyboard.py", "__name:=params_keyboard _markers_file:=" + kPkg +
                                                            "/config/markers.yaml _recorder_file:=none _recordr:=/rec");
  EXPECT_NE(keyboard.status, 0) << keyboard.output;
  EXPECT_NE(keyboard.status, 124) << keyboard.output;
  EXPECT_NE(keyboard.output.find("parameter /params_keyboard/recordr is not one of node /params_keyboard's"),
            std::string::npos)
      << keyboard.output;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "params_mistyped");
  return RUN_ALL_TESTS();
}
