// carried_objects on the real table's graph: B1's segment is reported DONE only once its
// carrier R1's follower reported DONE and the tracker sees B1 at its end point; with R1
// done and B1 short of it, FAILED naming B1. The test plays coordinator, follower and
// tracker.
#include <gtest/gtest.h>

#include <map>
#include <mutex>

#include <ros/ros.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>

#include "exec_common.h"

namespace {

std::mutex mu;

ddace::EntityArray entities(double bx, double by) {
  ddace::EntityArray m;
  m.header.stamp = ros::Time::now();
  m.header.frame_id = "table";
  const std::vector<std::tuple<std::string, std::string, double, double>> all = {
      {"R1", "robot", 0.20, 0.30}, {"B1", "object", bx, by}, {"G1", "goal", 0.60, 0.30}};
  for (const auto& [name, kind, x, y] : all) {
    ddace::Entity e;
    e.name = name, e.kind = kind, e.pose.x = x, e.pose.y = y, e.visible = true, e.stale = false;
    e.last_seen = m.header.stamp;
    m.entities.push_back(e);
  }
  return m;
}

}  // namespace

TEST(CarriedObjects, ABoxIsDoneWhenTrackedAtItsEndAfterItsCarrier) {
  ros::NodeHandle nh;
  std::map<uint32_t, ddace::SegmentStatus> last;  // B1's statuses by segment id
  auto status =
      nh.subscribe<ddace::SegmentStatus>("/robots/B1/segment_status", 20, [&](const ddace::SegmentStatus::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        last[m->segment_id] = *m;
      });
  ros::Publisher b1 = nh.advertise<ddace::Segment>("/robots/B1/segment", 5);
  ros::Publisher r1 = nh.advertise<ddace::Segment>("/robots/R1/segment", 5);
  ros::Publisher r1_status = nh.advertise<ddace::SegmentStatus>("/robots/R1/segment_status", 5);
  ros::Publisher tracker = nh.advertise<ddace::EntityArray>("/ddace/entities", 5);
  ASSERT_TRUE(exec_test::waitFor(
      [&] {
        return b1.getNumSubscribers() > 0 && r1.getNumSubscribers() > 0 && r1_status.getNumSubscribers() > 0 &&
               tracker.getNumSubscribers() > 0 && status.getNumPublishers() > 0;
      },
      20.0))
      << "carried_objects is not connected";
  const auto statusOf = [&](uint32_t id) {
    std::lock_guard<std::mutex> l(mu);
    return last.count(id) ? int(last[id].status) : -1;
  };
  const auto done = [&](uint32_t id) {
    r1_status.publish(exec_test::segmentStatus("R1", id, ddace::SegmentStatus::DONE));
  };

  // Run 1: R1 carries B1 to G1 (step 1); B1 is seen on its end point only after R1 is done.
  r1.publish(exec_test::straightSegment("R1", "carry", 10, 1, 0.20, 0.30, 0.556, 0.30, 0.03));
  b1.publish(exec_test::straightSegment("B1", "carry", 11, 1, 0.25, 0.30, 0.60, 0.30, 0.03));
  ASSERT_TRUE(exec_test::waitFor([&] { return statusOf(11) == ddace::SegmentStatus::ACCEPTED; }, 5.0));
  tracker.publish(entities(0.60, 0.30));  // there, but its carrier is not done: not yet
  ros::WallDuration(0.5).sleep();
  EXPECT_EQ(statusOf(11), ddace::SegmentStatus::ACCEPTED);
  done(10);
  tracker.publish(entities(0.605, 0.30));
  ASSERT_TRUE(exec_test::waitFor([&] { return statusOf(11) == ddace::SegmentStatus::DONE; }, 5.0))
      << "status " << statusOf(11);

  // Run 2: R1 done, B1 left 10 cm short: FAILED naming B1 after settle_s.
  r1.publish(exec_test::straightSegment("R1", "carry", 20, 2, 0.20, 0.30, 0.556, 0.30, 0.03));
  b1.publish(exec_test::straightSegment("B1", "carry", 21, 2, 0.25, 0.30, 0.60, 0.30, 0.03));
  ASSERT_TRUE(exec_test::waitFor([&] { return statusOf(21) == ddace::SegmentStatus::ACCEPTED; }, 5.0));
  tracker.publish(entities(0.50, 0.30));
  ros::WallDuration(0.3).sleep();  // seen short of its end before its carrier is done (two topics: no order)
  done(20);
  ASSERT_TRUE(exec_test::waitFor([&] { return statusOf(21) == ddace::SegmentStatus::FAILED; }, 5.0))
      << "status " << statusOf(21);
  std::lock_guard<std::mutex> l(mu);
  EXPECT_NE(last[21].message.find("B1 is 10.0 cm from its end point"), std::string::npos) << last[21].message;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "carried_objects_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
