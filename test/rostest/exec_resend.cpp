// coordinator_node delivers at least once: a decision request, a path request or a segment
// that nobody acknowledges goes out again with the same id (a node that subscribed late
// misses the first copy), and the run still completes with one decision per step.
#include <gtest/gtest.h>

#include <atomic>
#include <functional>
#include <map>
#include <tuple>
#include <mutex>
#include <thread>

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

#include "exec_common.h"

namespace {

std::mutex mu;
std::map<uint32_t, int> decision_copies, path_copies, segment_copies;
std::vector<uint32_t> decision_ids;
ddace::CoordinatorState state;

}  // namespace

TEST(ExecResend, LostMessagesAreSentAgainWithTheSameId) {
  ros::NodeHandle nh;
  ros::Publisher decision_pub = nh.advertise<ddace::Decision>("/ddace/decision", 5);
  ros::Publisher path_pub = nh.advertise<ddace::PathResponse>("/ddace/path", 5);
  ros::Publisher status_pub = nh.advertise<ddace::SegmentStatus>("/robots/R1/segment_status", 5);

  // Sequence node: drops the first copy of each request; step 1 = R1:move:G1, then END.
  auto on_request = [&](const ddace::DecisionRequest::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    if (++decision_copies[m->id] == 1) {
      decision_ids.push_back(m->id);
      return;
    }
    if (decision_copies[m->id] > 2) return;
    decision_pub.publish(exec_test::oneTokenThenEnd(*m, "R1", "move", "G1", 1.0));
  };
  // Path node: drops the first copy; answers with a straight line.
  auto on_path = [&](const ddace::PathRequest::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    if (++path_copies[m->id] == 2) path_pub.publish(exec_test::straightPath(*m));
  };
  // R1's executor: drops the first copy of the segment, reports the second done.
  auto on_segment = [&](const ddace::Segment::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    if (m->mode != ddace::Segment::MODE_FOLLOW || ++segment_copies[m->segment_id] != 2) return;
    status_pub.publish(exec_test::segmentStatus("R1", m->segment_id, ddace::SegmentStatus::DONE));
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
  // The tracker: R1 at (0.2, 0.2), R2 at (0.5, 0.2), G1 at (0.8, 0.8); R1 "arrives" when done.
  exec_test::FakeTracker tracker([&]() -> std::vector<exec_test::TrackedEntity> {
    std::lock_guard<std::mutex> l(mu);
    const bool done = !segment_copies.empty() && segment_copies.begin()->second >= 2;
    return {{"R1", "robot", done ? 0.8 : 0.2, done ? 0.8 : 0.2}, {"R2", "robot", 0.5, 0.2}, {"G1", "goal", 0.8, 0.8}};
  });
  std::string why;
  ASSERT_TRUE(exec_test::trigger("/coordinator/start", 20.0, &why)) << why;
  const bool finished = exec_test::waitFor(
      mu, [&] { return state.state == ddace::CoordinatorState::FINISHED; }, 20.0);
  std::lock_guard<std::mutex> l(mu);
  ASSERT_TRUE(finished) << "state " << state.state_name << ": " << state.reason;
  ASSERT_EQ(decision_ids.size(), 2u) << "one decision per step plus END, whatever the copies";
  for (const auto& [id, n] : decision_copies) EXPECT_GE(n, 2) << "decision request " << id << " was not re-sent";
  ASSERT_EQ(path_copies.size(), 1u);
  EXPECT_GE(path_copies.begin()->second, 2);
  ASSERT_EQ(segment_copies.size(), 1u);
  EXPECT_GE(segment_copies.begin()->second, 2);
  ASSERT_EQ(state.steps.size(), 1u);
  EXPECT_EQ(state.steps[0].tokens[0].target, "G1");
  ASSERT_EQ(state.goal_conditions_met.size(), 1u);
  EXPECT_TRUE(state.goal_conditions_met[0]);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_resend_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
