// rostest: calibrate_hamster.py refuses to fit a robot that did not follow its commands (see
// hamster_calibration_still.test): a fit to a still robot gives a tiny m/s per unit, which
// the bridge would turn into full speed for every motion.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

TEST(HamsterCalibration, ARobotThatDoesNotFollowItsCommandsIsNotCalibrated) {
  ros::NodeHandle pnh("~");
  std::string script, config;
  ASSERT_TRUE(pnh.getParam("script", script));
  ASSERT_TRUE(pnh.getParam("config", config));
  const std::string dir = ::testing::TempDir() + "/ddace_calibration_still_" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  const std::string output = dir + "/calibration.yaml", log = dir + "/calibrate.log";
  const std::string command = "timeout 60 /usr/bin/python3 '" + script +
                              "' __name:=calibrate_hamster _robot:=R2 _config:='" + config +
                              "' _entities_topic:=/mock_hamster/entities '_speeds:=[0.03]' _run_s:=1.0 _output:='" +
                              output + "' > '" + log + "' 2>&1";
  const int status = std::system(command.c_str());
  std::stringstream out;
  out << std::ifstream(log).rdbuf();
  ASSERT_TRUE(WIFEXITED(status)) << out.str();
  EXPECT_EQ(WEXITSTATUS(status), 1) << out.str();
  EXPECT_NE(out.str().find("robot R2 moved"), std::string::npos) << out.str();
  EXPECT_NE(out.str().find("did not follow the command"), std::string::npos) << out.str();
  EXPECT_FALSE(std::filesystem::exists(output)) << "a calibration was written:\n" << out.str();
  std::filesystem::remove_all(dir);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hamster_calibration_still_test");
  return RUN_ALL_TESTS();
}
