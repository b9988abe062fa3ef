// rostest: calibrate_hamster.py recovers the true speed per wheel unit of a mock Hamster
// (driven through the real bridge, observed through the mock's tracker-like entities).
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

TEST(HamsterCalibration, MeasuresTheTrueSpeedPerUnit) {
  ros::NodeHandle pnh("~");
  std::string output;
  double truth = 0.0;
  ASSERT_TRUE(pnh.getParam("output", output));
  ASSERT_TRUE(pnh.getParam("true_mps_per_unit", truth));
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(100.0);
  YAML::Node result;
  while (ros::WallTime::now() < end && ros::ok()) {
    try {
      result = YAML::Load(ddace::readTextFile(output));
      if (result["right_mps_per_unit"]) break;
    } catch (const ddace::Error&) {
      // not written yet
    } catch (const YAML::Exception&) {
      // still being written
    }
    ros::WallDuration(0.2).sleep();
  }
  ASSERT_TRUE(result["left_mps_per_unit"]) << "calibrate_hamster.py wrote no result to " << output;
  // R2's config calibration is 0.002 (left) / 0.0025 (right): the script must not just echo it.
  EXPECT_NEAR(result["left_mps_per_unit"].as<double>(), truth, 0.02 * truth);
  EXPECT_NEAR(result["right_mps_per_unit"].as<double>(), truth, 0.02 * truth);
  EXPECT_EQ(result["runs"].as<int>(), 4);
  std::remove(output.c_str());
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hamster_calibration_test");
  return RUN_ALL_TESTS();
}
