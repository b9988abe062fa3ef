// rostest (vision_intrinsics_file.test and vision_intrinsics_none.test, one binary):
// where the tracker's intrinsics come from, and what it says without any.
// ~expect = "file": a calibration file is used (poses within 5 mm, diagnostics name
// the file, height correction on); "none": one warning on the console with the
// expected error of raised markers, diagnostics WARN "height correction off".
#include <gtest/gtest.h>

#include <cmath>
#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>

#include "ddace/EntityArray.h"
#include "vision_scene.h"

TEST(VisionIntrinsics, TheTrackerSaysWhereItsIntrinsicsComeFrom) {
  ros::NodeHandle nh, pnh("~");
  std::string expect;
  ASSERT_TRUE(pnh.getParam("expect", expect)) << "test parameter ~expect missing";
  std::mutex mutex;
  std::vector<std::string> warnings;
  diagnostic_msgs::DiagnosticStatus status;
  bool have_status = false;
  double max_pos = 0;
  int outputs = 0;
  ros::Time start;
  auto log_sub = nh.subscribe<rosgraph_msgs::Log>("/rosout", 100, [&](const rosgraph_msgs::Log::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    if (m->name == "/tracker" && m->level == rosgraph_msgs::Log::WARN) warnings.push_back(m->msg);
  });
  auto diag_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& s : m->status)
          if (s.name.find("tracker") != std::string::npos) {
            status = s;
            have_status = true;
          }
      });
  auto sub = nh.subscribe<ddace::EntityArray>("/ddace/entities", 100, [&](const ddace::EntityArray::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    if (start.isZero()) return;
    const double t = (m->header.stamp - start).toSec();
    for (size_t i = 0; i < m->entities.size() && i < 5; ++i) {
      if (!m->entities[i].visible) continue;
      double x, y, th;
      vision_test::truePose(static_cast<int>(i), t, x, y, th);
      max_pos = std::max(max_pos, std::hypot(m->entities[i].pose.x - x, m->entities[i].pose.y - y));
    }
    ++outputs;
  });
  ros::Publisher truth = nh.advertise<ddace::EntityArray>("/ddace/true_entities", 10);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (truth.getNumSubscribers() == 0 && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
  ASSERT_GT(truth.getNumSubscribers(), 0u) << "synthetic_camera_node did not subscribe";
  {
    std::lock_guard<std::mutex> lock(mutex);
    start = ros::Time::now();
  }
  ros::Rate rate(50);
  while (ros::ok()) {
    const ros::Time now = ros::Time::now();
    const double t = (now - start).toSec();
    if (t > 3.0) break;
    truth.publish(vision_test::truthMsg(t, now));
    rate.sleep();
  }
  ros::WallDuration(1.5).sleep();  // the last diagnostics

  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_GE(outputs, 20);
  ASSERT_TRUE(have_status) << "no diagnostic status from the tracker";
  std::string intrinsics, correction;
  for (const auto& kv : status.values) {
    if (kv.key == "intrinsics") intrinsics = kv.value;
    if (kv.key == "height correction") correction = kv.value;
  }
  int no_intrinsics_warnings = 0;
  for (const auto& w : warnings) no_intrinsics_warnings += w.find("no intrinsics") != std::string::npos;
  if (expect == "file") {
    EXPECT_NE(intrinsics.find("synthetic_camera_info.yaml"), std::string::npos) << intrinsics;
    EXPECT_EQ(correction, "on");
    EXPECT_EQ(status.level, diagnostic_msgs::DiagnosticStatus::OK) << status.message;
    EXPECT_EQ(no_intrinsics_warnings, 0);
    EXPECT_LT(max_pos, 0.005) << "raised markers not corrected";
  } else {
    EXPECT_EQ(intrinsics, "none");
    EXPECT_EQ(correction, "off: no intrinsics");
    EXPECT_EQ(status.level, diagnostic_msgs::DiagnosticStatus::WARN) << status.message;
    ASSERT_EQ(no_intrinsics_warnings, 1) << "expected exactly one warning about the missing intrinsics";
    for (const auto& w : warnings) {
      if (w.find("no intrinsics") == std::string::npos) continue;
      // 3.5 cm markers seen from 1.3 m: about 25 mm at the table's far corners.
      EXPECT_NE(w.find("3.5 cm above the table are off by up to 2"), std::string::npos) << w;
    }
    EXPECT_GT(max_pos, 0.006) << "without intrinsics raised markers should show their parallax";
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "vision_intrinsics_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
