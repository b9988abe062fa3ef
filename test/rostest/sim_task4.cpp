// Task 4 through launch/execute_real.launch with sim:=true: the real-robot graph (tracker,
// hamster bridge, coordinator, sequence, gp_path, path follower) on a simulated table.
// Nothing but the protocol-level mock Hamsters' wheels moves the robots' bodies
// (sim_table_node), and nothing but the tracker's measurements of the synthetic camera's
// images tells the coordinator where they are. The run must finish as the ground truth
// says, with every goal condition met, and the robots must truly have moved there.
#include "exec_common.h"

#include <cmath>
#include <mutex>

#include <ddace/HamsterMockState.h>

namespace {

/// Demonstrations the model is trained on: Task 4 is one fixed sequence; 10 decide it.
constexpr int kTrainDemos = 10;

}  // namespace

TEST(SimTask4, ExecuteRealSimFinishesOnTheSimulatedTable) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("sim_task4");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "task4", kTrainDemos, 1, 4);
  const std::string model = exec_test::trainModel(dir);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");

  // What moved the robots (the mock Hamsters' wire) and where they truly went.
  std::mutex mu;
  std::map<std::string, uint64_t> motoring_lines;
  int tracked = 0;
  ros::Subscriber mock_sub = nh.subscribe<ddace::HamsterMockState>("/mock_hamster/state", 100,
                                                                   [&](const ddace::HamsterMockState::ConstPtr& m) {
                                                                     const std::lock_guard<std::mutex> l(mu);
                                                                     motoring_lines[m->robot] = m->motoring_lines;
                                                                   });
  const exec_test::TrueTable truth(nh);
  ros::Subscriber tracked_sub =
      nh.subscribe<ddace::EntityArray>("/ddace/entities", 10, [&](const ddace::EntityArray::ConstPtr& m) {
        const std::lock_guard<std::mutex> l(mu);
        if (!m->entities.empty() && m->entities.front().visible) ++tracked;
      });

  exec_test::Watcher watch(nh, test.spec);
  exec_test::Launch graph(
      {files.launch_file, "task:=" + dir + "/test", "model:=" + model, "sim:=true", "autostart:=false",
       "monitor:=false", "execution:=" + files.config_file, "mock_link_dir:=" + dir + "/links"},
      dir + "/launch.log");
  const exec_test::RunEnd run = exec_test::runToEnd(watch, 40.0, 90.0);
  ASSERT_TRUE(exec_test::finished(run));
  const ddace::CoordinatorState& s = run.state;
  EXPECT_EQ(exec_test::executedSteps(s), exec_test::truthSteps(test.demos.front(), test.spec));
  ASSERT_EQ(s.goal_conditions_met.size(), test.spec.goal_conditions.size());
  EXPECT_TRUE(exec_test::goalConditionsMet(s));
  EXPECT_TRUE(exec_test::wheelsStopped(watch));

  auto first_truth = truth.first(), last_truth = truth.last();
  const std::lock_guard<std::mutex> l(mu);
  EXPECT_GT(tracked, 100) << "the tracker published too few measured poses";
  // The goal conditions hold on the simulated table itself, not only in what the tracker saw.
  for (const auto& c : test.spec.goal_conditions) {
    ASSERT_TRUE(last_truth.count(c.entity) && last_truth.count(c.at)) << c.entity;
    const auto& a = last_truth[c.entity].pose;
    const auto& b = last_truth[c.at].pose;
    EXPECT_LT(std::hypot(a.x - b.x, a.y - b.y), c.tolerance) << c.entity << " truly at " << c.at;
  }
  // Every robot was driven over the radio protocol and moved its body.
  for (const auto& e : test.spec.entities) {
    if (e.kind != ddace::task::EntityKind::Robot) continue;
    EXPECT_GT(motoring_lines[e.name], 50u) << e.name << ": the mock Hamster got no motoring lines";
    const auto& a = first_truth[e.name].pose;
    const auto& b = last_truth[e.name].pose;
    EXPECT_GT(std::hypot(a.x - b.x, a.y - b.y), 0.1) << e.name << " did not move on the simulated table";
  }
}

int main(int argc, char** argv) {
  return exec_test::rostestMain(argc, argv, "sim_task4_test");
}
