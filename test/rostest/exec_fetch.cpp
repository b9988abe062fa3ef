// A carry through launch/execute_sim.launch as shipped (fetch, replayed: the nearest robot
// drives to the box, then carries it to the goal; mock robots on Box2D, the safety filter,
// the execution monitor writing the run's record). What a user depends on: the box rides in
// front of its carrier and ends on the goal, the run finishes without a collision, and the
// record's minimum clearance is over the bodies that must keep apart -- not the carrier and
// the load it pushes, which touch by design.
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include <ddace/EntityArray.h>

#include "ddace/exec/safety_filter.h"
#include "ddace/ros/execution_monitor.h"
#include "exec_common.h"

TEST(ExecFetch, TheBoxRidesInFrontOfItsCarrierToTheGoalAndTheRecordMeasuresTheOthers) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("fetch");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "fetch", 3, 1);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  const ddace::task::TaskSpec& spec = test.spec;
  const int box = spec.entityIndex("B1");
  ASSERT_GE(box, 0);
  const double contact = ddace::exec::bodyShape(spec, box).radius_m + ddace::task::kDefaultRobotRadius;
  // Every frame in which the box is at a robot (within contact + 5 mm) that drives: is it
  // in front of it (within 45 degrees of its heading)?
  std::mutex mu;
  int riding = 0, in_front = 0;
  std::map<std::string, ddace::Entity> last;
  auto sub = nh.subscribe<ddace::EntityArray>("/ddace/entities", 50, [&](const ddace::EntityArray::ConstPtr& m) {
    std::lock_guard<std::mutex> l(mu);
    const ddace::Entity* b = nullptr;
    for (const auto& e : m->entities)
      if (e.name == "B1") b = &e;
    if (!b) return;
    for (const auto& e : m->entities) {
      if (e.kind != "robot") continue;
      const auto before = last.find(e.name);
      const bool drives = before != last.end() &&
                          std::hypot(e.pose.x - before->second.pose.x, e.pose.y - before->second.pose.y) > 0.0005;
      const double dx = b->pose.x - e.pose.x, dy = b->pose.y - e.pose.y, d = std::hypot(dx, dy);
      if (drives && d < contact + 0.005) {
        ++riding;
        in_front += (dx * std::cos(e.pose.theta) + dy * std::sin(e.pose.theta)) > d * std::cos(M_PI / 4);
      }
      last[e.name] = e;
    }
  });
  exec_test::Watcher watch(nh, spec);
  const std::string run_dir = dir + "/run";
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "train:=" + dir + "/train", "autostart:=true",
                           "monitor:=true", "run_dir:=" + run_dir, "config:=" + files.config_file},
                          dir + "/launch.log");
  const exec_test::RunEnd run = exec_test::waitRunEnd(watch, 60.0);  // autostart: it ends by itself
  ASSERT_TRUE(exec_test::finished(run));
  const ddace::CoordinatorState& s = run.state;
  for (size_t i = 0; i < s.goal_conditions_met.size(); ++i)
    EXPECT_TRUE(s.goal_conditions_met[i]) << s.goal_conditions[i];
  {
    std::lock_guard<std::mutex> l(mu);
    ASSERT_GT(riding, 30) << "the box was hardly ever at a driving robot: it did not ride";
    EXPECT_GT(in_front, 0.9 * riding) << in_front << " of " << riding << " frames in front of its carrier";
  }
  // The monitor writes the record and ends the launch.
  ASSERT_TRUE(graph.waitExit(30.0)) << "the launch did not end after the run finished";
  const nlohmann::json r = nlohmann::json::parse(exec_test::readFile(run_dir + "/result.json"));
  EXPECT_EQ(r.at("collisions"), 0) << r.dump();
  EXPECT_EQ(r.at("osr"), 1) << r.dump();
  ASSERT_FALSE(r.at("min_clearance_m").is_null()) << r.dump();
  // The carrier and its load touch by design (the record showed -0.33 cm for them): not
  // measured, as in `ddace eval`. What is measured keeps apart.
  EXPECT_GT(r.at("min_clearance_m").get<double>(), 0.0) << r.dump();
  std::cout << "exec_fetch: " << in_front << " of " << riding << " riding frames in front; " << r.dump() << "\n";
}

int main(int argc, char** argv) {
  return exec_test::rostestMain(argc, argv, "exec_fetch_test");
}
