// Task 2 (11 robots, replayed) through launch/execute_sim.launch as shipped: mock robots on
// Box2D and the safety filter in the path follower (config/execution.yaml's defaults). What
// a user depends on: no two bodies closer than contact (tracking noise aside) at any time,
// and the run finishes -- motions end at contact, so nothing holds a robot off its end.
#include <cmath>

#include <ddace/EntityArray.h>

#include "ddace/exec/safety_filter.h"
#include "ddace/ros/execution_monitor.h"
#include "exec_common.h"

TEST(ExecBodies, Task2FinishesWithNoTwoBodiesBelowContact) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("bodies");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "task2", 3, 1, 11);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  const ddace::task::TaskSpec& spec = test.spec;
  std::mutex mu;
  double min_gap = 1e9;
  std::string closest;
  auto sub = nh.subscribe<ddace::EntityArray>("/ddace/entities", 50, [&](const ddace::EntityArray::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    for (size_t a = 0; a < m->entities.size(); ++a)
      for (size_t b = a + 1; b < m->entities.size(); ++b) {
        const int i = spec.entityIndex(m->entities[a].name), j = spec.entityIndex(m->entities[b].name);
        if (i < 0 || j < 0) continue;
        const auto si = ddace::exec::bodyShape(spec, i), sj = ddace::exec::bodyShape(spec, j);
        if (!si.obstacle || !sj.obstacle) continue;
        const double gap =
            std::hypot(m->entities[a].pose.x - m->entities[b].pose.x, m->entities[a].pose.y - m->entities[b].pose.y) -
            si.radius_m - sj.radius_m;
        if (gap < min_gap) min_gap = gap, closest = m->entities[a].name + "-" + m->entities[b].name;
      }
  });
  exec_test::Watcher watch(nh, spec);
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "train:=" + dir + "/train", "autostart:=false",
                           "monitor:=false", "config:=" + files.config_file});
  const std::string started = exec_test::startRun(watch, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  const bool ended = exec_test::waitFor(
      [&] {
        const auto c = watch.stateCode();
        return c == ddace::CoordinatorState::FINISHED || c == ddace::CoordinatorState::ABORTED;
      },
      90.0);
  const ddace::CoordinatorState s = watch.state();
  ASSERT_TRUE(ended) << "the run did not end by itself within 90 s (a silent freeze?); state " << s.state_name;
  EXPECT_EQ(s.state, ddace::CoordinatorState::FINISHED) << s.state_name << ": " << s.reason;
  std::lock_guard<std::mutex> l(mu);
  // The execution monitor's collision tolerance: two touching bodies' measured gap has the
  // tracking noise of both (1 mm per axis each).
  const double tolerance = ddace::nodes::ExecutionMonitorNode::Params().collision_overlap_m;
  EXPECT_GT(min_gap, -tolerance) << closest << " overlapped by " << -min_gap * 100 << " cm";
  std::cout << "exec_bodies: " << s.state_name << " (" << s.reason << "), closest " << closest << " " << min_gap * 100
            << " cm\n";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_bodies_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
