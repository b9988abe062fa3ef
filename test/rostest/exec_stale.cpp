// path_follower_node alone, fed by this test as the tracker: it drives on fresh poses and
// zeroes the wheels on a stale pose, on a pose time-out, on the e-stop topic and on an
// invalid segment; a pose stale for stale_fail_s fails the segment.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>

#include <ros/ros.h>
#include <std_msgs/Bool.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "exec_common.h"

namespace {

using exec_test::Wheel;
using exec_test::zeroWithinOneCycle;

class FollowerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    wheels_sub_ =
        nh_.subscribe<ddace::WheelCommand>("/robots/R1/wheels", 500, [this](const ddace::WheelCommand::ConstPtr& m) {
          std::lock_guard<std::mutex> l(mu_);
          wheels_.push_back({m->header.stamp, m->left_mps, m->right_mps, "/path_follower"});
        });
    status_sub_ = nh_.subscribe<ddace::SegmentStatus>("/robots/R1/segment_status", 100,
                                                      [this](const ddace::SegmentStatus::ConstPtr& m) {
                                                        std::lock_guard<std::mutex> l(mu_);
                                                        statuses_.push_back(*m);
                                                      });
    segment_pub_ = nh_.advertise<ddace::Segment>("/robots/R1/segment", 10);
    entities_pub_ = nh_.advertise<ddace::EntityArray>("/ddace/entities", 10);
    estop_pub_ = nh_.advertise<std_msgs::Bool>("/ddace/estop", 1, true);
    tracker_ = std::thread([this] {
      ros::Rate rate(50);
      while (running_) {
        if (publish_) {
          ddace::EntityArray a;
          a.header.stamp = ros::Time::now();
          a.header.frame_id = "table";
          ddace::Entity e;
          e.name = "R1";
          e.kind = "robot";
          e.pose.x = 0.2;
          e.pose.y = 0.2;
          e.visible = !stale_;
          e.stale = stale_;
          a.entities.push_back(e);
          entities_pub_.publish(a);
          std::lock_guard<std::mutex> l(mu_);
          last_pose_ = a.header.stamp;
          if (stale_ && first_stale_ == ros::Time()) first_stale_ = a.header.stamp;
        }
        rate.sleep();
      }
    });
    ASSERT_TRUE(wait(
        [&] {
          return segment_pub_.getNumSubscribers() > 0 && wheels_sub_.getNumPublishers() > 0 &&
                 status_sub_.getNumPublishers() > 0 && entities_pub_.getNumSubscribers() > 0 &&
                 estop_pub_.getNumSubscribers() > 0;
        },
        20.0))
        << "path_follower_node did not connect";
    std_msgs::Bool off;
    off.data = false;
    estop_pub_.publish(off);
    ros::Duration(0.2).sleep();
  }
  void TearDown() override {
    // The subscriptions end before the fixture's members do: a callback still running on the
    // spinner's threads would otherwise push into wheels_ or statuses_ while they are destroyed
    // (seen once as "double free or corruption" under load). shutdown() waits for it.
    wheels_sub_.shutdown();
    status_sub_.shutdown();
    running_ = false;
    tracker_.join();
  }

  static bool wait(const std::function<bool()>& pred, double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (pred()) return true;
      ros::WallDuration(0.005).sleep();
    }
    return pred();
  }

  void sendSegment(uint32_t id, double nan_at = -1) {
    ddace::Segment s;
    s.header.stamp = ros::Time::now();
    s.header.frame_id = "table";
    s.mode = ddace::Segment::MODE_FOLLOW;
    s.entity = "R1";
    s.segment_id = id;
    for (int i = 0; i <= 20; ++i) {
      geometry_msgs::PoseStamped p;
      p.pose.position.x = 0.2 + 0.02 * i;
      p.pose.position.y = 0.2;
      if (i == nan_at) p.pose.position.x = std::nan("");
      p.pose.orientation.w = 1;
      s.path.poses.push_back(p);
    }
    s.arrival_radius_m = 0.03;
    segment_pub_.publish(s);
  }

  bool hasStatus(uint32_t id, uint8_t status, std::string* message = nullptr) {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& s : statuses_)
      if (s.segment_id == id && s.status == status) {
        if (message) *message = s.message;
        return true;
      }
    return false;
  }

  /// The wheel commands so far.
  std::vector<Wheel> wheels() {
    std::lock_guard<std::mutex> l(mu_);
    return wheels_;
  }
  ros::Time firstStale() {
    std::lock_guard<std::mutex> l(mu_);
    return first_stale_;
  }
  ros::Time lastPose() {
    std::lock_guard<std::mutex> l(mu_);
    return last_pose_;
  }

  bool driving() {
    std::lock_guard<std::mutex> l(mu_);
    return !wheels_.empty() && (wheels_.back().left != 0 || wheels_.back().right != 0);
  }

  /// Every command stamped after `t` is zero (and there is at least one).
  ::testing::AssertionResult allZeroAfter(const ros::Time& t) {
    std::lock_guard<std::mutex> l(mu_);
    int n = 0;
    for (const auto& w : wheels_)
      if (w.stamp > t) {
        ++n;
        if (w.left != 0 || w.right != 0)
          return ::testing::AssertionFailure()
                 << "non-zero command " << w.left << ", " << w.right << " at " << (w.stamp - t).toSec() << " s";
      }
    if (n == 0) return ::testing::AssertionFailure() << "no command after the event";
    return ::testing::AssertionSuccess();
  }

  ros::NodeHandle nh_;
  ros::Subscriber wheels_sub_, status_sub_;
  ros::Publisher segment_pub_, entities_pub_, estop_pub_;
  std::thread tracker_;
  std::atomic<bool> running_{true}, publish_{true}, stale_{false};
  std::mutex mu_;
  std::vector<Wheel> wheels_;
  std::vector<ddace::SegmentStatus> statuses_;
  ros::Time last_pose_, first_stale_;  ///< stamps of the last pose sent, of the first stale one
};

TEST_F(FollowerTest, IdleRobotGetsZeroCommands) {
  ASSERT_TRUE(wait([&] { return allZeroAfter(ros::Time(0)); }, 2.0));
  EXPECT_TRUE(allZeroAfter(ros::Time(0)));
}

TEST_F(FollowerTest, StalePoseZeroesWheelsThenFailsTheSegment) {
  sendSegment(1);
  ASSERT_TRUE(wait([&] { return hasStatus(1, ddace::SegmentStatus::ACCEPTED) && driving(); }, 5.0));
  stale_ = true;
  ros::Duration(0.3).sleep();
  // Zero in the callback that receives the stale flag: at most the cycle under way after it.
  ASSERT_NE(firstStale(), ros::Time());
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), firstStale()));
  EXPECT_FALSE(hasStatus(1, ddace::SegmentStatus::FAILED)) << "failed before stale_fail_s";
  std::string why;
  ASSERT_TRUE(wait([&] { return hasStatus(1, ddace::SegmentStatus::FAILED, &why); }, 3.0));
  EXPECT_NE(why.find("stale"), std::string::npos) << why;
  // Fresh again: the failed segment stays failed, the robot stays put.
  stale_ = false;
  const ros::Time t2 = ros::Time::now();
  ros::Duration(0.3).sleep();
  EXPECT_TRUE(allZeroAfter(t2));
}

TEST_F(FollowerTest, PoseTimeoutZeroesWheels) {
  sendSegment(2);
  ASSERT_TRUE(wait([&] { return driving(); }, 5.0));
  publish_ = false;  // the tracker goes silent
  ros::Duration(0.6).sleep();
  // The first cycle after pose_timeout_s (0.25) without a pose is zero (the pose's receipt
  // may lag its stamp by the cycle under way).
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), lastPose() + ros::Duration(0.25)));
  publish_ = true;
  ASSERT_TRUE(wait([&] { return driving(); }, 2.0)) << "does not resume on fresh poses";
}

TEST_F(FollowerTest, EstopTopicZeroesAtOnceAndRefusesSegments) {
  sendSegment(3);
  ASSERT_TRUE(wait([&] { return driving(); }, 5.0));
  std_msgs::Bool on;
  on.data = true;
  const ros::Time t = ros::Time::now();
  estop_pub_.publish(on);
  ros::Duration(0.3).sleep();
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), t));
  EXPECT_TRUE(hasStatus(3, ddace::SegmentStatus::ABORTED));
  sendSegment(4);
  std::string why;
  ASSERT_TRUE(wait([&] { return hasStatus(4, ddace::SegmentStatus::ABORTED, &why); }, 2.0));
  EXPECT_NE(why.find("e-stop"), std::string::npos);
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), t)) << "driven while the e-stop holds";
  std_msgs::Bool off;
  off.data = false;
  estop_pub_.publish(off);
  ros::Duration(0.2).sleep();  // the release and the segment travel on different connections
  sendSegment(5);
  ASSERT_TRUE(wait([&] { return driving(); }, 5.0)) << "does not drive after the e-stop is released";
}

TEST_F(FollowerTest, StopSegmentAndInvalidPathZeroTheWheels) {
  sendSegment(6);
  ASSERT_TRUE(wait([&] { return driving(); }, 5.0));
  ddace::Segment stop;
  stop.mode = ddace::Segment::MODE_STOP;
  stop.entity = "R1";
  const ros::Time t = ros::Time::now();
  segment_pub_.publish(stop);
  ASSERT_TRUE(wait([&] { return hasStatus(6, ddace::SegmentStatus::ABORTED); }, 2.0));
  ros::Duration(0.2).sleep();
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), t));

  sendSegment(7, 5);  // point 5 is NaN
  std::string why;
  ASSERT_TRUE(wait([&] { return hasStatus(7, ddace::SegmentStatus::FAILED, &why); }, 2.0));
  EXPECT_NE(why.find("point 5"), std::string::npos) << why;
  EXPECT_FALSE(driving());
}

TEST_F(FollowerTest, CoordinatorGoneStopsTheRobot) {
  sendSegment(8);
  ASSERT_TRUE(wait([&] { return driving(); }, 5.0));
  const ros::Time t = ros::Time::now();
  segment_pub_.shutdown();  // the only publisher of R1's segments goes: the coordinator died
  std::string why;
  ASSERT_TRUE(wait([&] { return hasStatus(8, ddace::SegmentStatus::ABORTED, &why); }, 2.0));
  EXPECT_NE(why.find("coordinator is gone"), std::string::npos) << why;
  ros::Duration(0.2).sleep();
  ros::Time stopped;
  {
    std::lock_guard<std::mutex> l(mu_);
    for (const auto& st : statuses_)
      if (st.segment_id == 8 && st.status == ddace::SegmentStatus::ABORTED) stopped = st.header.stamp;
  }
  // The follower zeroes in the cycle that finds the link gone, right after saying so.
  EXPECT_TRUE(zeroWithinOneCycle(wheels(), stopped));
  EXPECT_FALSE(driving());
  std::cout << "the segment publisher went; the follower stopped R1 " << (stopped - t).toSec() << " s later\n";
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_stale_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
