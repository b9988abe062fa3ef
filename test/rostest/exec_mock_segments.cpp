// mock_robots forgets an object's segment when it ends: a later robot segment that would
// carry it (same step, action and target -- a new run's step numbers start again) must not
// make the finished object ride. The test plays coordinator and follower: B1 is moved 2 cm
// along its own segment to DONE, then R1, beside it, gets a segment "R1:carry:G1" of the
// same step and drives backwards; B1 must stay where its segment left it. A node the launch
// did not name publishes on R1's wheels all along: refused, counted and named.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <mutex>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "exec_common.h"

namespace {

std::mutex mu;

}  // namespace

TEST(ExecMockSegments, AFinishedObjectSegmentDoesNotMakeTheObjectRide) {
  ros::NodeHandle nh;
  std::map<std::string, ddace::Entity> at;
  uint8_t b1_status = 255;
  auto entities = nh.subscribe<ddace::EntityArray>("/ddace/entities", 10, [&](const ddace::EntityArray::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    for (const auto& e : m->entities) at[e.name] = e;
  });
  auto status =
      nh.subscribe<ddace::SegmentStatus>("/robots/B1/segment_status", 10, [&](const ddace::SegmentStatus::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        if (m->segment_id == 1) b1_status = m->status;
      });
  ros::Publisher b1 = nh.advertise<ddace::Segment>("/robots/B1/segment", 5, true);
  ros::Publisher r1 = nh.advertise<ddace::Segment>("/robots/R1/segment", 5, true);
  ros::Publisher wheels = nh.advertise<ddace::WheelCommand>("/robots/R1/wheels", 5);
  ASSERT_TRUE(exec_test::waitFor(
      mu, [&] { return at.count("B1") && at.count("R1"); }, 20.0))
      << "no /ddace/entities";
  ASSERT_TRUE(exec_test::waitFor([&] { return b1.getNumSubscribers() > 0 && r1.getNumSubscribers() > 0; }, 10.0));

  b1.publish(exec_test::straightSegment("B1", "carry", 1, 0, 0.30, 0.30, 0.32, 0.30, 0.005));
  ASSERT_TRUE(exec_test::waitFor(
      mu, [&] { return b1_status == ddace::SegmentStatus::DONE; }, 15.0))
      << "B1's segment did not finish (status " << int(b1_status) << ")";
  double bx, by;
  {
    std::lock_guard<std::mutex> l(mu);
    bx = at["B1"].pose.x, by = at["B1"].pose.y;
  }
  // R1, 7 cm from B1 (where a carrier counts as at its load), carries to G1 in step 0.
  r1.publish(exec_test::straightSegment("R1", "carry", 2, 0, 0.25, 0.30, 0.60, 0.30, 0.005));
  ros::WallDuration(0.5).sleep();
  for (int i = 0; i < 50; ++i) {  // 1 s backwards, away from B1
    ddace::WheelCommand w;
    w.header.stamp = ros::Time::now();
    w.left_mps = w.right_mps = -0.05;
    wheels.publish(w);
    ros::WallDuration(0.02).sleep();
  }
  ddace::WheelCommand stop;
  stop.header.stamp = ros::Time::now();
  wheels.publish(stop);
  ros::WallDuration(0.3).sleep();
  std::lock_guard<std::mutex> l(mu);
  EXPECT_LT(at["R1"].pose.x, 0.23) << "R1 did not drive backwards";
  EXPECT_LT(std::hypot(at["B1"].pose.x - bx, at["B1"].pose.y - by), 0.005)
      << "B1 moved with R1 from (" << bx << ", " << by << ") to (" << at["B1"].pose.x << ", " << at["B1"].pose.y
      << "): its finished segment paired with R1's";
}

// The intruder's commands are refused and counted where a user looks, as on the bridge:
// the robot's diagnostics name it and turn WARN.
TEST(ExecMockSegments, TheDiagnosticsCountAndNameTheIntruder) {
  ros::NodeHandle nh;
  std::mutex m;
  diagnostic_msgs::DiagnosticStatus r1;
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& a) {
        for (const auto& st : a->status)
          if (st.name == "mock_robots: mock robot R1" && st.level == diagnostic_msgs::DiagnosticStatus::WARN) {
            const std::lock_guard<std::mutex> l(m);
            r1 = st;
          }
      });
  std::string foreign;
  const bool named = exec_test::waitFor(
      m,
      [&] {
        for (const auto& kv : r1.values)
          if (kv.key == "foreign commands") foreign = kv.value;
        return foreign.find("last from /intruder") != std::string::npos;
      },
      30.0);
  const std::lock_guard<std::mutex> l(m);
  ASSERT_TRUE(named) << "no WARN naming /intruder in R1's diagnostics; last: " << r1.message << " " << foreign;
  EXPECT_GT(std::stoul(foreign), 0u) << foreign;
  EXPECT_NE(r1.message.find("wheel commands from /intruder refused"), std::string::npos) << r1.message;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_mock_segments");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
