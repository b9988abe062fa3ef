// rostest: launch/tabletop.launch (mock:=true) with the shipped config/hamsters.yaml.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <map>
#include <mutex>

#include <ddace/HamsterMockState.h>
#include <ddace/WheelCommand.h>

#include "ddace/hamster/config.h"

TEST(HamsterTabletop, EveryConfiguredRobotIsFoundAndDriven) {
  ros::NodeHandle nh, pnh("~");
  std::string path;
  ASSERT_TRUE(pnh.getParam("config", path));
  const auto config = ddace::hamster::loadBridgeConfig(path);
  ASSERT_FALSE(config.robots.empty());
  std::mutex mutex;
  std::map<std::string, ddace::HamsterMockState> states;
  auto sub = nh.subscribe<ddace::HamsterMockState>("/mock_hamster/state", 100,
                                                   [&](const ddace::HamsterMockState::ConstPtr& m) {
                                                     std::lock_guard<std::mutex> lock(mutex);
                                                     states[m->robot] = *m;
                                                   });
  std::map<std::string, ros::Publisher> pubs;
  std::map<std::string, int> want;
  for (const auto& r : config.robots) {
    pubs[r.name] = nh.advertise<ddace::WheelCommand>("/robots/" + r.name + "/wheels", 1);
    want[r.name] = ddace::hamster::wheelUnitsFromSpeeds(r.calibration, 0.03, 0.03).left;
    ASSERT_NE(want[r.name], 0);
  }
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(30.0);
  bool all = false;
  while (!all && ros::WallTime::now() < end && ros::ok()) {
    for (auto& [name, pub] : pubs) {
      ddace::WheelCommand c;
      c.header.stamp = ros::Time::now();
      c.left_mps = c.right_mps = 0.03;
      pub.publish(c);
    }
    ros::WallDuration(0.02).sleep();
    std::lock_guard<std::mutex> lock(mutex);
    all = true;
    for (const auto& [name, units] : want) {
      all = all && states.count(name) && states[name].left_units == units && states[name].right_units == units;
    }
  }
  EXPECT_TRUE(all) << "not every robot of " << path << " was driven through tabletop.launch";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hamster_tabletop_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
