// coordinator_node believes only what it can check: a DONE on R1's topic naming another
// entity, with an invalid code, with R2's segment id, or while its own tracked pose of R1
// is 0.25 m from the goal changes nothing; the next decision goes out only once R1 is
// really tracked at the goal. Its ~state carries the live distance meanwhile.
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>
#include <tuple>

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <ddace/CoordinatorState.h>
#include <ddace/Decision.h>
#include <ddace/DecisionRequest.h>
#include <ddace/EntityArray.h>
#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "exec_common.h"

namespace {

std::mutex mu;
std::vector<ddace::DecisionRequest> requests;
std::vector<ddace::Segment> segments;
ddace::CoordinatorState state;
double r1_x = 0.2, r1_y = 0.2;

}  // namespace

TEST(ExecVerify, ForgedAndPrematureDonesAreIgnored) {
  ros::NodeHandle nh;
  ros::Publisher decision_pub = nh.advertise<ddace::Decision>("/ddace/decision", 5);
  ros::Publisher path_pub = nh.advertise<ddace::PathResponse>("/ddace/path", 5);
  ros::Publisher status_pub = nh.advertise<ddace::SegmentStatus>("/robots/R1/segment_status", 5);
  ros::Publisher status2_pub = nh.advertise<ddace::SegmentStatus>("/robots/R2/segment_status", 5);
  // Sequence node: step 1 = R1:move:G1, then END.
  auto on_request = [&](const ddace::DecisionRequest::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    for (const auto& r : requests)
      if (r.id == m->id) return;
    requests.push_back(*m);
    decision_pub.publish(exec_test::oneTokenThenEnd(*m, "R1", "move", "G1", 0.9));
  };
  auto on_path = [&](const ddace::PathRequest::ConstPtr& m) { path_pub.publish(exec_test::straightPath(*m)); };
  auto on_segment = [&](const ddace::Segment::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    if (m->mode == ddace::Segment::MODE_FOLLOW) segments.push_back(*m);
  };
  ros::Subscriber a = nh.subscribe<ddace::DecisionRequest>("/ddace/decision_request", 10, on_request);
  ros::Subscriber b = nh.subscribe<ddace::PathRequest>("/ddace/path_request", 10, on_path);
  ros::Subscriber c = nh.subscribe<ddace::Segment>("/robots/R1/segment", 10, on_segment);
  ros::Subscriber d = nh.subscribe<ddace::Segment>("/robots/R2/segment", 10, [&](const ddace::Segment::ConstPtr&) {});
  ros::Subscriber e =
      nh.subscribe<ddace::CoordinatorState>("/coordinator/state", 10, [&](const ddace::CoordinatorState::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        state = *m;
      });
  exec_test::FakeTracker tracker([&]() -> std::vector<exec_test::TrackedEntity> {
    std::lock_guard<std::mutex> l(mu);
    return {{"R1", "robot", r1_x, r1_y}, {"R2", "robot", 0.5, 0.2}, {"G1", "goal", 0.8, 0.8}};
  });
  std::string why;
  ASSERT_TRUE(exec_test::trigger("/coordinator/start", 20.0, &why)) << why;
  ASSERT_TRUE(exec_test::waitFor(
      mu, [] { return !segments.empty(); }, 10.0));
  const uint32_t id = segments.front().segment_id;
  auto status = [&](ros::Publisher& pub, const std::string& entity, uint32_t seg, uint8_t code) {
    pub.publish(exec_test::segmentStatus(entity, seg, code));
  };
  // R1 is 0.25 m from G1 when its "DONE"s come.
  {
    std::lock_guard<std::mutex> l(mu);
    r1_x = 0.8 - 0.25, r1_y = 0.8;
  }
  ros::WallDuration(0.3).sleep();
  status(status_pub, "R9", id, ddace::SegmentStatus::DONE);        // another entity's name
  status(status_pub, "R1", id, 42);                                // no such code
  status(status2_pub, "R2", id, ddace::SegmentStatus::DONE);       // R1's segment on R2's topic
  status(status_pub, "R1", id + 100, ddace::SegmentStatus::DONE);  // no such segment
  status(status_pub, "R1", id, ddace::SegmentStatus::DONE);        // right, but R1 is not there
  ros::WallDuration(1.0).sleep();
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_EQ(requests.size(), 1u) << "a forged or premature DONE was believed";
    EXPECT_EQ(state.state, ddace::CoordinatorState::EXECUTING) << state.state_name << ": " << state.reason;
    ASSERT_EQ(state.segments.size(), 1u);
    EXPECT_NEAR(state.segments[0].distance_to_goal_m, 0.25, 0.01);
    EXPECT_TRUE(state.segments[0].done_claimed);
    ASSERT_EQ(state.last_decision.size(), 1u);
    EXPECT_DOUBLE_EQ(state.last_decision[0].probability, 0.9);
  }
  // R1 really arrives: the claimed DONE counts now, and the next decision goes out.
  {
    std::lock_guard<std::mutex> l(mu);
    r1_x = 0.8 - 0.01;
  }
  ASSERT_TRUE(exec_test::waitFor(
      mu, [] { return requests.size() == 2; }, 5.0))
      << "no decision after the real arrival";
  ASSERT_TRUE(exec_test::waitFor(
      mu, [] { return state.state == ddace::CoordinatorState::FINISHED; }, 5.0))
      << state.state_name;
}

// The answers of the sequence and path nodes are checked too: a decision for another
// request id is ignored, one naming an entity the task does not have aborts naming it, and
// so does a path with a non-finite point (naming the token).
TEST(ExecVerify, WrongDecisionsAndPathsAreRefused) {
  ros::NodeHandle nh;
  ros::Publisher decision_pub = nh.advertise<ddace::Decision>("/ddace/decision", 5);
  ros::Publisher path_pub = nh.advertise<ddace::PathResponse>("/ddace/path", 5);
  std::vector<ddace::DecisionRequest> asked;
  std::vector<ddace::PathRequest> paths_asked;
  ros::Subscriber a = nh.subscribe<ddace::DecisionRequest>("/ddace/decision_request", 10,
                                                           [&](const ddace::DecisionRequest::ConstPtr& m) {
                                                             std::lock_guard<std::mutex> l(mu);
                                                             asked.push_back(*m);
                                                           });
  ros::Subscriber b =
      nh.subscribe<ddace::PathRequest>("/ddace/path_request", 10, [&](const ddace::PathRequest::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        paths_asked.push_back(*m);
      });
  ros::Subscriber c = nh.subscribe<ddace::Segment>("/robots/R1/segment", 10, [&](const ddace::Segment::ConstPtr&) {});
  ros::Subscriber d = nh.subscribe<ddace::Segment>("/robots/R2/segment", 10, [&](const ddace::Segment::ConstPtr&) {});
  ros::Subscriber e =
      nh.subscribe<ddace::CoordinatorState>("/coordinator/state", 10, [&](const ddace::CoordinatorState::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        state = *m;
      });
  exec_test::FakeTracker tracker([]() -> std::vector<exec_test::TrackedEntity> {
    return {{"R1", "robot", 0.2, 0.2}, {"R2", "robot", 0.5, 0.2}, {"G1", "goal", 0.8, 0.8}};
  });
  auto token = [](const std::string& entity) {
    ddace::Token t;
    t.entity = entity;
    t.action = "move";
    t.target = "G1";
    return t;
  };
  // A fresh run whose first decision request has come; returns its id.
  auto startRun = [&]() -> uint32_t {
    std_srvs::Trigger t;
    ros::service::call("/coordinator/reset", t);
    {
      std::lock_guard<std::mutex> l(mu);
      asked.clear();
      paths_asked.clear();
    }
    std::string why;
    EXPECT_TRUE(exec_test::trigger("/coordinator/start", 10.0, &why)) << why;
    EXPECT_TRUE(exec_test::waitFor(
        mu, [&] { return !asked.empty(); }, 10.0));
    std::lock_guard<std::mutex> l(mu);
    return asked.empty() ? 0 : asked.front().id;
  };

  // 1. An answer to another request changes nothing; one naming R9 aborts.
  uint32_t id = startRun();
  ASSERT_NE(id, 0u);
  ddace::Decision other;
  other.id = id + 100;
  other.tokens.push_back(token("R1"));
  decision_pub.publish(other);
  ros::WallDuration(0.5).sleep();
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_EQ(state.state, ddace::CoordinatorState::DECIDING) << state.state_name << ": " << state.reason;
    EXPECT_TRUE(paths_asked.empty()) << "a decision for another request was acted on";
  }
  ddace::Decision unknown;
  unknown.id = id;
  unknown.tokens.push_back(token("R9"));
  decision_pub.publish(unknown);
  ASSERT_TRUE(exec_test::waitFor(
      mu, [] { return state.state == ddace::CoordinatorState::ABORTED; }, 5.0))
      << state.state_name;
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_NE(state.reason.find("R9"), std::string::npos) << state.reason;
  }

  // 2. A path with a NaN point aborts, naming the token.
  id = startRun();
  ASSERT_NE(id, 0u);
  ddace::Decision right;
  right.id = id;
  right.tokens.push_back(token("R1"));
  decision_pub.publish(right);
  ASSERT_TRUE(exec_test::waitFor(
      mu, [&] { return !paths_asked.empty(); }, 5.0));
  ddace::PathResponse bad;
  {
    std::lock_guard<std::mutex> l(mu);
    bad = exec_test::straightPath(paths_asked.front());
  }
  bad.path.poses.front().pose.position.y = std::numeric_limits<double>::quiet_NaN();
  path_pub.publish(bad);
  ASSERT_TRUE(exec_test::waitFor(
      mu, [] { return state.state == ddace::CoordinatorState::ABORTED; }, 5.0))
      << state.state_name;
  {
    std::lock_guard<std::mutex> l(mu);
    EXPECT_NE(state.reason.find("R1:move:G1"), std::string::npos) << state.reason;
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_verify_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
