// launch/record.launch sim:=true with the shipped recorder and marker files (Task 4's
// robots R1..R4 and goal G1, laid out in rows): the test steers R2 onto G1 from what the
// simulated table shows, as a person at the teleop's keys would, between /recorder/start
// and /recorder/stop. The saved demonstration must hold that motion as the tracker saw it
// -- R2 from its row onto G1, the others still -- and the label the recorder inferred
// from it: R2 moves to G1.
#include "exec_common.h"

#include <cmath>
#include <mutex>

namespace {

struct Pose {
  double x = 0, y = 0, theta = 0;
};

}  // namespace

TEST(SimRecord, RecordsARobotDrivenOnTheSimulatedTable) {
  ros::NodeHandle nh, pnh("~");
  std::string launch_file;
  ASSERT_TRUE(pnh.getParam("launch_file", launch_file));
  const exec_test::ScratchDir scratch("sim_record");
  const std::string& dir = scratch;
  const std::string out = dir + "/demos_task";

  std::mutex mu;
  std::map<std::string, Pose> truth;
  ros::Subscriber truth_sub =
      nh.subscribe<ddace::EntityArray>("/ddace/true_entities", 10, [&](const ddace::EntityArray::ConstPtr& m) {
        const std::lock_guard<std::mutex> l(mu);
        for (const auto& e : m->entities) truth[e.name] = {e.pose.x, e.pose.y, e.pose.theta};
      });
  ros::Publisher wheels = nh.advertise<ddace::WheelCommand>("/robots/R2/wheels", 5);

  exec_test::Launch graph(
      {launch_file, "sim:=true", "keyboard:=false", "teleop:=false", "rviz:=false", "output_dir:=" + out},
      dir + "/launch.log");
  std::string message;
  ASSERT_TRUE(exec_test::trigger("/recorder/start", 40.0, &message)) << "the recorder did not start: " << message;
  ASSERT_EQ(wheels.getNumSubscribers(), 1u) << "sim_table does not listen to /robots/R2/wheels";
  std::map<std::string, Pose> start;
  {
    const std::lock_guard<std::mutex> l(mu);
    start = truth;
  }
  ASSERT_TRUE(start.count("R2") && start.count("G1"));

  // Steer R2 onto G1: turn toward it, drive while facing it, stop on it.
  auto drive = [&](double left, double right) {
    ddace::WheelCommand c;
    c.header.stamp = ros::Time::now();
    c.left_mps = left;
    c.right_mps = right;
    wheels.publish(c);
  };
  const bool arrived = exec_test::waitFor(
      [&] {
        Pose r, g;
        {
          const std::lock_guard<std::mutex> l(mu);
          r = truth["R2"], g = truth["G1"];
        }
        const double dx = g.x - r.x, dy = g.y - r.y;
        if (std::hypot(dx, dy) < 0.01) return true;
        const double err = std::remainder(std::atan2(dy, dx) - r.theta, 2 * M_PI);
        const double v = std::abs(err) < 0.3 ? std::min(0.12, 2 * std::hypot(dx, dy)) : 0.0;
        const double w = std::clamp(3.0 * err, -3.0, 3.0);
        drive(v - w * 0.015, v + w * 0.015);
        ros::Duration(0.05).sleep();
        return false;
      },
      30.0);
  drive(0, 0);
  ASSERT_TRUE(arrived) << "R2 did not reach G1 on the simulated table";
  ros::Duration(1.5).sleep();  // still at the end, as a person lets go
  ASSERT_TRUE(exec_test::trigger("/recorder/stop", 10.0, &message)) << message;
  std::cout << "sim_record: " << message << "\n";

  const ddace::task::TaskDir task = ddace::task::loadTaskDir(out);
  ASSERT_EQ(task.demos.size(), 1u);
  const ddace::task::Demonstration& demo = task.demos.front();
  const int r2 = task.spec.entityIndex("R2"), g1 = task.spec.entityIndex("G1");
  ASSERT_GE(r2, 0);
  ASSERT_GE(g1, 0);
  ASSERT_GT(demo.rows(), 20u);
  // As the tracker saw it: R2 from where it stood onto G1; every other body still.
  const auto& first = demo.positions.front();
  const auto& last = demo.positions.back();
  EXPECT_LT((first[r2] - Eigen::Vector2d(start["R2"].x, start["R2"].y)).norm(), 0.02);
  EXPECT_LT((last[r2] - last[g1]).norm(), 0.03) << "R2 ends on G1";
  EXPECT_GT((last[r2] - first[r2]).norm(), 0.3);
  for (size_t i = 0; i < task.spec.entities.size(); ++i) {
    if (static_cast<int>(i) == r2) continue;
    EXPECT_LT((last[i] - first[i]).norm(), 0.02) << task.spec.entities[i].name;
  }
  // The recorder inferred the one step a person would label: R2 moves to G1.
  ASSERT_EQ(demo.steps.size(), 1u) << message;
  ASSERT_EQ(demo.steps.front().tokens.size(), 1u) << message;
  EXPECT_EQ(ddace::task::tokenKey(demo.steps.front().tokens.front(), task.spec), "R2:move:G1") << message;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_record_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
