// path_follower_node knows which bodies stand still from the segments it hears: an entity
// driven elsewhere moves while its segment runs and stands once its executor reports the
// segment ended (DONE). Held by a standing body, a robot goes round it on the side its
// command turns to; by a moving one, by the right-hand rule (exec::SafetyFilter). The test
// plays coordinator, tracker and the box's executor: B1 right in front of R1 (within the
// filter's margin), R1's path leading ahead and to the left. While B1's segment runs, R1,
// held, turns right; once B1 reported DONE, R1's next segment turns it left. B1's next
// segment's DONE arriving before the segment itself (separate connections, or the
// coordinator re-sending it): the segment has ended, B1 still stands, R1 still turns left.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <mutex>
#include <vector>

#include <ros/ros.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "ddace/exec/safety_filter.h"
#include "ddace/task/task_spec.h"

#include "exec_common.h"

namespace {

std::mutex mu;
constexpr double kArrivalM = 0.024;  // the segments' arrival radius (a stop radius)

}  // namespace

TEST(ExecFollowerStanding, ABodyGoneRoundByTheRightHandRuleUntilItsSegmentEnded) {
  ros::NodeHandle nh, pnh("~");
  std::string task;
  ASSERT_TRUE(pnh.getParam("task", task));
  const ddace::task::TaskSpec spec = ddace::task::readTaskYaml(task + "/task.yaml");
  const double r1_radius = ddace::exec::bodyShape(spec, spec.entityIndex("R1")).radius_m;
  const double b1_radius = ddace::exec::bodyShape(spec, spec.entityIndex("B1")).radius_m;
  const ddace::exec::SafetyParams sp;
  // B1 right ahead of R1, 1 mm inside the filter's margin: forward is blocked.
  const double rx = 0.20, ry = 0.30, bx = rx + r1_radius + b1_radius + sp.margin_m + sp.projection_m - 0.001;

  std::vector<ddace::WheelCommand> wheels;
  auto wheel_sub =
      nh.subscribe<ddace::WheelCommand>("/robots/R1/wheels", 100, [&](const ddace::WheelCommand::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        wheels.push_back(*m);
      });
  ros::Publisher entities = nh.advertise<ddace::EntityArray>("/ddace/entities", 5);
  ros::Publisher r1 = nh.advertise<ddace::Segment>("/robots/R1/segment", 5, true);
  ros::Publisher b1 = nh.advertise<ddace::Segment>("/robots/B1/segment", 5, true);
  ros::Publisher b1_status = nh.advertise<ddace::SegmentStatus>("/robots/B1/segment_status", 5, true);
  // The tracker: everybody where they are, 30 times a second.
  ros::WallTimer tracker = nh.createWallTimer(ros::WallDuration(1.0 / 30), [&](const ros::WallTimerEvent&) {
    ddace::EntityArray a;
    a.header.stamp = ros::Time::now();
    a.header.frame_id = "table";
    for (const auto& [name, kind, x, y] : std::vector<std::tuple<std::string, std::string, double, double>>{
             {"R1", "robot", rx, ry}, {"B1", "object", bx, ry}, {"G1", "goal", 0.6, 0.5}}) {
      ddace::Entity e;
      e.name = name;
      e.kind = kind;
      e.pose.x = x;
      e.pose.y = y;
      e.visible = true;
      e.last_seen = a.header.stamp;
      a.entities.push_back(e);
    }
    entities.publish(a);
  });
  ASSERT_TRUE(exec_test::waitFor(
      [&] {
        return entities.getNumSubscribers() > 0 && r1.getNumSubscribers() > 0 && b1.getNumSubscribers() > 0 &&
               b1_status.getNumSubscribers() > 0 && wheel_sub.getNumPublishers() > 0;
      },
      20.0))
      << "path_follower is not up";
  ros::WallDuration(0.5).sleep();  // poses known

  // The mean yaw rate commanded over the last 0.4 s of `for_s` seconds of segment `id`.
  const auto turn = [&](uint32_t id, double for_s) {
    r1.publish(exec_test::straightSegment("R1", "move", id, 1, rx, ry, rx + 0.25, ry + 0.08,
                                          kArrivalM));  // ahead, to the left
    ros::WallDuration(for_s).sleep();
    std::lock_guard<std::mutex> l(mu);
    const ros::Time from = ros::Time::now() - ros::Duration(0.4);
    double w = 0;
    int n = 0;
    for (const auto& c : wheels)
      if (c.header.stamp >= from) w += c.right_mps - c.left_mps, ++n;
    return n ? w / n : 0.0;
  };
  // B1 is on its way (its segment runs): a moving body, gone round keeping it on the left.
  b1.publish(exec_test::straightSegment("B1", "carry", 1, 1, bx, ry, bx + 0.1, ry,
                                        kArrivalM));  // not R1's load: another action
  ros::WallDuration(0.3).sleep();
  const double moving = turn(2, 1.5);
  EXPECT_LT(moving, -0.01) << "held by a moving body, R1 does not turn right (right-hand rule)";
  // B1's executor says it arrived: it stands; R1's next segment goes round it on the left.
  ddace::SegmentStatus done;
  done.header.stamp = ros::Time::now();
  done.entity = "B1";
  done.segment_id = 1;
  done.status = ddace::SegmentStatus::DONE;
  done.progress = 1;
  b1_status.publish(done);
  ros::WallDuration(0.3).sleep();
  const double standing = turn(3, 1.5);
  EXPECT_GT(standing, 0.01) << "held by a standing body, R1 does not turn left, where its path leads";
  done.header.stamp = ros::Time::now();
  done.segment_id = 4;
  b1_status.publish(done);
  ros::WallDuration(0.2).sleep();
  b1.publish(
      exec_test::straightSegment("B1", "carry", 4, 2, bx, ry, bx + 0.1, ry, kArrivalM));  // arrives after its end
  ros::WallDuration(0.3).sleep();
  const double late = turn(5, 1.5);
  EXPECT_GT(late, 0.01) << "a segment that arrived after its end status is kept: B1 counted as moving";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_follower_standing");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
