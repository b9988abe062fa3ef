// One scenario, Task 4 (four robots; the last ends at contact with the robot standing on
// the goal) replaying its test demonstration, run twice: through the core simulator with
// bodies (exec::runTrial with exec::BodiesExecution, as `ddace eval --execution diffdrive`)
// and through the ROS graph of launch/execute_sim.launch (coordinator, path_follower, mock
// robots with bodies), both with config/execution.yaml's controller, filter and simulated
// Hamsters and the same paths and end points (the train demonstrations'). What the
// simulator certifies is what drives the robots: the same decisions, every motion done,
// each robot stopped where the other run stopped it (within twice the arrival radius: each
// stops within the stop radius of an end point decided from where the bodies stood; the
// second of two robots sent to one goal, held short beside the first, differs most: 4.8 cm
// seen), and
// the same bodies at one place (task::togetherDistance) with each other at the end (a pair
// together in one run within the arrival radius of it in the other). No wall-clock margin:
// the run is waited on (60 s for a run of about 15 s).
#include "exec_common.h"

#include <algorithm>

#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/execution_config.h"
#include "ddace/exec/replay.h"
#include "ddace/task/body_geometry.h"
#include "ddace/task/end_point.h"

namespace {

/// The pairs of bodies of `spec` within `slack_m` of one place with each other at `at`
/// (task::togetherDistance), "R3-R4".
std::set<std::string> togetherPairs(const ddace::task::TaskSpec& spec, const std::vector<Eigen::Vector2d>& at,
                                    double slack_m = 0) {
  std::set<std::string> out;
  for (size_t a = 0; a < at.size(); ++a)
    for (size_t b = a + 1; b < at.size(); ++b) {
      if (spec.entities[a].kind == ddace::task::EntityKind::Goal ||
          spec.entities[b].kind == ddace::task::EntityKind::Goal)
        continue;
      const int i = static_cast<int>(a), j = static_cast<int>(b);
      if ((at[a] - at[b]).norm() <= ddace::task::togetherDistance(spec, i, j) + slack_m)
        out.insert(spec.entities[a].name + "-" + spec.entities[b].name);
    }
  return out;
}

/// Whether every element of `a` is in `b`.
bool within(const std::set<std::string>& a, const std::set<std::string>& b) {
  return std::includes(b.begin(), b.end(), a.begin(), a.end());
}

/// The last /ddace/entities frame (the mock robots' measured poses).
class LastFrame {
 public:
  explicit LastFrame(ros::NodeHandle& nh)
      : sub_(nh.subscribe<ddace::EntityArray>("/ddace/entities", 5, [this](const ddace::EntityArray::ConstPtr& m) {
          const std::lock_guard<std::mutex> l(mu_);
          for (const auto& e : m->entities) at_[e.name] = Eigen::Vector2d(e.pose.x, e.pose.y);
        })) {}
  std::map<std::string, Eigen::Vector2d> at() const {
    const std::lock_guard<std::mutex> l(mu_);
    return at_;
  }

 private:
  mutable std::mutex mu_;
  std::map<std::string, Eigen::Vector2d> at_;
  ros::Subscriber sub_;  // last: its callback ends before the map goes
};

}  // namespace

TEST(ExecSameScenario, TheSimulatorAndTheRosGraphDecideStopAndTouchAlike) {
  namespace task = ddace::task;
  namespace exec = ddace::exec;
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("same_scenario");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "task4", 3, 1, 4);
  const task::TaskDir train = task::loadTaskDir(dir + "/train");
  const task::TaskDir test = task::loadTaskDir(dir + "/test");
  const task::Demonstration& scene = test.demos.front();

  // The core simulator.
  exec::BodiesExecutionParams p;
  p.config = exec::readExecutionConfig(files.config_file);
  p.arrival_radius_m = test.spec.arrival_radius;
  p.noise_m = p.config.robot.position_noise_m;
  exec::BodiesExecution bodies(p);
  const exec::DemonstrationPaths paths(train.spec, train.demos);
  const auto policy = [&](const std::vector<task::Snapshot>& h) { return exec::replayDecision(scene, h); };
  const auto gen = [&](const task::Token& t, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return paths.generate(t, a, b).points;
  };
  const exec::Trial sim =
      exec::runTrial(test.spec, scene, policy, gen, bodies, task::learnEndPoints(train.spec, train.demos));
  ASSERT_TRUE(sim.ended);
  EXPECT_TRUE(sim.failures.empty()) << sim.failures.front();
  EXPECT_TRUE(sim.body_report.collisions.empty());

  // The ROS graph.
  exec_test::Watcher watch(nh, test.spec);
  const LastFrame frame(nh);
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "train:=" + dir + "/train", "autostart:=false",
                           "monitor:=false", "config:=" + files.config_file});
  const exec_test::RunEnd run = exec_test::runToEnd(watch, 30.0, 60.0);
  ASSERT_TRUE(exec_test::finished(run));
  for (const auto& step : run.state.steps)
    for (size_t i = 0; i < step.tokens.size(); ++i)
      EXPECT_EQ(step.status[i], ddace::SegmentStatus::DONE) << step.tokens[i].entity << " in step " << step.index;

  // The same decisions.
  std::vector<std::vector<std::string>> decided;
  for (const task::Step& s : sim.predicted) {
    decided.emplace_back();
    for (const task::Token& t : s.tokens) decided.back().push_back(task::tokenKey(t, test.spec));
    std::sort(decided.back().begin(), decided.back().end());
  }
  EXPECT_EQ(exec_test::executedSteps(run.state), decided);

  // The same stops, and the same bodies together at the end.
  const auto ros_at = frame.at();
  std::vector<Eigen::Vector2d> graph_at = sim.final_positions;
  double farthest_m = 0;  // the largest difference of a robot's stop between the runs
  for (size_t i = 0; i < test.spec.entities.size(); ++i) {
    const auto& e = test.spec.entities[i];
    const auto it = ros_at.find(e.name);
    ASSERT_NE(it, ros_at.end()) << e.name << " never seen on /ddace/entities";
    graph_at[i] = it->second;
    if (e.kind != task::EntityKind::Robot) continue;
    farthest_m = std::max(farthest_m, (graph_at[i] - sim.final_positions[i]).norm());
    EXPECT_LE((graph_at[i] - sim.final_positions[i]).norm(), 2 * test.spec.arrival_radius)
        << e.name << " stopped at " << graph_at[i].transpose() << " on the graph, "
        << sim.final_positions[i].transpose() << " in the simulator";
  }
  // Together in one run, together within the arrival radius more in the other (a pair on
  // the edge may fall either side of it).
  const double slack = test.spec.arrival_radius;
  const std::set<std::string> together = togetherPairs(test.spec, sim.final_positions);
  const std::set<std::string> graph_together = togetherPairs(test.spec, graph_at);
  EXPECT_FALSE(together.empty()) << "the scenario ends with no contact to compare";
  EXPECT_TRUE(within(together, togetherPairs(test.spec, graph_at, slack)));
  EXPECT_TRUE(within(graph_together, togetherPairs(test.spec, sim.final_positions, slack)));
  std::cout << "exec_same_scenario: " << decided.size() << " steps; stops at most " << 100 * farthest_m
            << " cm apart; together at the end:";
  for (const auto& t : together) std::cout << " " << t;
  std::cout << "\n";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_same_scenario_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
