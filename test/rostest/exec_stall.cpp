// A stalled mock robot: its segment times out, the run aborts cleanly (without recovery at
// once; with it after re-planning it, and with a policy that reads the scene re-deciding its
// step, as often as coordinator/max_replans allows), every wheel is zero.
#include "exec_common.h"

using namespace exec_test;

// Without recovery (max_replans: 0, the paper's execution) the first time-out aborts.
TEST(ExecStall, SegmentTimeoutAbortsTheRunWithZeroWheels) {
  TaskGraph g("stall", "task4", 3, 1);
  const std::string config = g.config({{"coordinator", "segment_timeout_s", "8.0"},
                                       {"coordinator", "segment_timeout_per_m_s", "0.0"},
                                       {"coordinator", "max_replans", "0"}});
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args({"monitor:=false", "config:=" + config, "stalled:=[R2]"}));
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 30.0))
      << "state " << w.state().state_name;
  ros::Duration(0.5).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find("R2:move:R4"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("timed out"), std::string::npos) << s.reason;
  // R1 arrived, R2's segment was aborted, and no further step was decided.
  ASSERT_EQ(s.steps.size(), 1u);
  EXPECT_EQ(w.requests(), 1u);
  bool r2_aborted = false;
  for (const auto& [id, seg] : w.segments())
    if (seg.key == "R2:move:R4") r2_aborted = seg.end_status == ddace::SegmentStatus::ABORTED;
  EXPECT_TRUE(r2_aborted) << "R2's segment was not reported aborted";
  // The time-out is checked every control cycle: the coordinator zeroes every robot in the
  // check that finds it (before it announces the abort), the follower within its cycle.
  const ros::Time knew = w.firstStamp(ddace::CoordinatorState::ABORTED);
  ros::Time deadline;
  for (const auto& [id, seg] : w.segments())
    if (seg.key == "R2:move:R4") deadline = seg.sent + ros::Duration(8.0);
  for (const auto& [robot, cmds] : w.wheels()) {
    ASSERT_FALSE(cmds.empty());
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), deadline);
    ASSERT_NE(zero, ros::Time()) << robot << ": the coordinator published no zero after the time-out";
    EXPECT_LE(zero, knew) << robot;
    EXPECT_TRUE(zeroWithinOneCycle(from(cmds, "/path_follower"), zero)) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot;
    if (robot == "R2") {
      // R2 was driving (stalled) until then: how many of the follower's cycles passed
      // between the deadline and the coordinator's zero.
      int cycles = 0;
      for (const auto& c : from(cmds, "/path_follower"))
        if (c.stamp > deadline && c.stamp < zero) ++cycles;
      std::cout << "R2's segment timed out: the coordinator zeroed it " << (zero - deadline).toSec() << " s (" << cycles
                << " follower cycles) after the deadline\n";
      EXPECT_LE(cycles, 2) << "the time-out was noticed " << cycles << " control cycles late";
    }
  }
}

// With coordinator/max_replans: 1 the stalled robot's token is re-planned once from where it
// stands (a new segment), and when that times out too the run aborts naming why.
TEST(ExecStall, WithReplansAStalledRobotIsReplannedThenTheRunAbortsNamingWhy) {
  TaskGraph g("stall_replan", "task4", 3, 1);
  const std::string config = g.config({{"coordinator", "segment_timeout_s", "4.0"},
                                       {"coordinator", "segment_timeout_per_m_s", "0.0"},
                                       {"coordinator", "max_replans", "1"}});
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args({"monitor:=false", "config:=" + config, "stalled:=[R2]"}));
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 40.0))
      << "state " << w.state().state_name;
  ros::Duration(0.5).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find("R2:move:R4"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("timed out"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("max_replans = 1"), std::string::npos) << s.reason;
  std::vector<ros::Time> r2_sent;
  for (const auto& [id, seg] : w.segments())
    if (seg.key == "R2:move:R4") r2_sent.push_back(seg.sent);
  ASSERT_EQ(r2_sent.size(), 2u) << "R2's token was not sent again after its time-out";
  std::sort(r2_sent.begin(), r2_sent.end());
  EXPECT_GE((r2_sent[1] - r2_sent[0]).toSec(), 4.0) << "re-planned before its time-out";
  EXPECT_EQ(w.requests(), 1u) << "no further step was decided";
  for (const auto& [robot, cmds] : w.wheels()) {
    ASSERT_FALSE(cmds.empty()) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot << " still driving after the abort";
  }
}

// With a model whose decisions read the scene (deliver's scene network) and max_replans: 1,
// the node re-plans the stalled fetcher's token once, then decides the step again from the
// scene of now (a second decision request), re-plans that once, and aborts naming why.
TEST(ExecStall, WithALearnedSceneModelTheStepIsDecidedAgainBeforeTheRunAborts) {
  TaskGraph g("stall_redecide", "deliver", 20, 1);
  const std::string model = trainModel(g.dir());
  const std::string config = g.config({{"coordinator", "segment_timeout_s", "3.0"},
                                       {"coordinator", "segment_timeout_per_m_s", "0.0"},
                                       {"coordinator", "max_replans", "1"}});
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args({"model:=" + model, "monitor:=false", "config:=" + config, "stalled:=[R1, R2]"}));
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ABORTED; }, 60.0))
      << "state " << w.state().state_name;
  ros::Duration(0.5).sleep();
  const auto s = w.state();
  EXPECT_NE(s.reason.find("timed out"), std::string::npos) << s.reason;
  EXPECT_NE(s.reason.find("max_replans = 1"), std::string::npos) << s.reason;
  EXPECT_EQ(w.requests(), 2u) << "step 1 was not decided again after its re-plan timed out";
  ASSERT_EQ(s.steps.size(), 1u);
  int fetches = 0;
  for (const auto& [id, seg] : w.segments()) fetches += seg.key.find(":move:B1") != std::string::npos;
  EXPECT_EQ(fetches, 4) << "sent, re-planned, sent again by the new decision, re-planned";
  for (const auto& [robot, cmds] : w.wheels()) {
    ASSERT_FALSE(cmds.empty()) << robot;
    EXPECT_TRUE(cmds.back().zero()) << robot << " still driving after the abort";
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_stall_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
