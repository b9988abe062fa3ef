// A model of another task with the same entity names — Task 2 trained with 4
// robots (R1..R4, G1) given for Task 4 — is refused by the sequence node and the gp_path
// node with a message that says what differs; the launched graph then never starts a run
// (the start is refused, no wheel ever turns) and the monitor still leaves a report.
// ~allow_other_task lets a deliberate transfer through.
#include "exec_common.h"

#include <chrono>
#include <cstdio>

#include "ddace/ros/gp_path.h"
#include "ddace/ros/sequence.h"
#include "ddace/tasks/rule_zoo.h"

using namespace exec_test;

namespace {

/// Task 4 (train, test) and a Task 2 model with 4 robots, once for every test.
struct Setup {
  ScratchDir scratch{"other_task"};
  std::string task4, model;
  Setup() {
    task4 = std::string(scratch) + "/task4";
    generateTask(task4, "task4", 3, 1, 4);
    const std::string task2 = std::string(scratch) + "/task2";
    generateTask(task2, "task2", 4, 1, 4);
    ddace::tgn::TrainOptions o;
    o.max_epochs = 5;  // what is checked is the task, not how well it was learned
    model = std::string(scratch) + "/task2_model";
    ddace::pipeline::trainModel(ddace::task::loadTaskDir(task2 + "/train"), o, model, nullptr);
  }
};

const Setup& setup() {
  static const Setup s;
  return s;
}

/// The error the node class throws on construction with these private parameters, or "".
template <typename Node>
std::string refusal(const std::string& ns, const std::map<std::string, std::string>& params, bool allow) {
  ros::NodeHandle nh, pnh("~" + ns);
  for (const auto& [k, v] : params) pnh.setParam(k, v);
  pnh.setParam("allow_other_task", allow);
  try {
    Node node(nh, pnh);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(OtherTask, TheSequenceNodeRefusesAnotherTasksModel) {
  const std::map<std::string, std::string> params = {
      {"task", setup().task4 + "/test"}, {"policy", "model"}, {"model", setup().model}};
  const std::string e = refusal<ddace::nodes::SequenceNode>("sequence_under_test", params, false);
  EXPECT_NE(e.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << e;
  EXPECT_NE(e.find("goal conditions:"), std::string::npos) << e;
  EXPECT_NE(e.find(setup().model), std::string::npos) << e;
  EXPECT_NE(e.find("allow_other_task"), std::string::npos) << e;
  EXPECT_EQ(refusal<ddace::nodes::SequenceNode>("sequence_transfer", params, true), "");
}

TEST(OtherTask, TheGpPathNodeRefusesAnotherTasksLibrary) {
  const std::map<std::string, std::string> params = {
      {"task", setup().task4 + "/test"}, {"source", "library"}, {"library", setup().model}};
  const std::string e = refusal<ddace::nodes::GpPathNode>("gp_path_under_test", params, false);
  EXPECT_NE(e.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << e;
  EXPECT_NE(e.find("allow_other_task"), std::string::npos) << e;
  EXPECT_EQ(refusal<ddace::nodes::GpPathNode>("gp_path_transfer", params, true), "");
}

// Other team sizes (docs/tgn.md): a model of a rule the scene states, trained with 3 robots,
// is taken by the sequence and gp_path nodes for the same rule with 5 robots (bound by kind,
// without ~allow_other_task); a fixed order (Task 2 with 4 robots) is refused for 5 naming why,
// even as a deliberate transfer (Task 2's name has its team size: another task without it).
TEST(OtherTask, TheNodesTakeAModelOfAnotherTeamSizeWhereTheSceneStatesTheRule) {
  const std::string dir = std::string(setup().scratch) + "/sizes";
  uint64_t rule = 0;
  ASSERT_TRUE(ddace::tasks::parseZooFamily("zoo:nearest-goals", rule));
  ddace::task::writeTaskDir(ddace::tasks::generateZoo(rule, 6, 1, {}, {3, 0, 4}), dir + "/three");
  ddace::task::writeTaskDir(ddace::tasks::generateZoo(rule, 1, 2, {}, {5, 0, 6}), dir + "/five");
  ddace::tgn::TrainOptions o;
  o.max_epochs = 5;  // what is checked is the binding, not how well it was learned
  o.without = {ddace::tgn::Rule::Ensemble};
  ddace::pipeline::trainModel(ddace::task::loadTaskDir(dir + "/three"), o, dir + "/model", nullptr);
  EXPECT_EQ(refusal<ddace::nodes::SequenceNode>(
                "sequence_five", {{"task", dir + "/five"}, {"policy", "model"}, {"model", dir + "/model"}}, false),
            "");
  EXPECT_EQ(refusal<ddace::nodes::GpPathNode>(
                "gp_path_five", {{"task", dir + "/five"}, {"source", "library"}, {"library", dir + "/model"}}, false),
            "");
  generateTask(dir + "/task2_five", "task2", 1, 1, 5);
  const std::string e = refusal<ddace::nodes::SequenceNode>(
      "sequence_task2_five", {{"task", dir + "/task2_five/test"}, {"policy", "model"}, {"model", setup().model}}, true);
  EXPECT_NE(e.find("fixed order"), std::string::npos) << e;
}

TEST(OtherTask, TheRunDoesNotStartAndNoWheelTurns) {
  ros::NodeHandle nh;
  const Files files = Files::fromParams();
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(setup().task4 + "/test");
  const std::string run_dir = std::string(setup().scratch) + "/run";
  Watcher watch(nh, test.spec);
  Launch graph({files.launch_file, "task:=" + setup().task4 + "/test", "train:=" + setup().task4 + "/train",
                "model:=" + setup().model, "autostart:=false", "monitor:=true", "run_dir:=" + run_dir,
                "config:=" + files.config_file});
  // The coordinator comes up; the two refusing nodes exit, so every start is refused.
  ASSERT_TRUE(waitFor([] { return ros::service::exists("/coordinator/start", false); }, 30.0));
  std::string message;
  EXPECT_FALSE(trigger("/coordinator/start", 10.0, &message)) << "a run started with another task's model";
  EXPECT_NE(message, "");
  EXPECT_EQ(pidOfNode("/sequence"), -1) << "the sequence node still runs with another task's model";
  EXPECT_EQ(pidOfNode("/gp_path"), -1) << "the gp_path node still runs with another task's library";
  EXPECT_EQ(watch.requests(), 0u) << "a decision was asked for";
  for (const auto& [robot, cmds] : watch.wheels())
    for (const auto& c : cmds) {
      EXPECT_EQ(c.left, 0.0) << robot;
      EXPECT_EQ(c.right, 0.0) << robot;
    }
  EXPECT_NE(watch.stateCode(), ddace::CoordinatorState::EXECUTING);
  graph.interrupt();
  ASSERT_TRUE(graph.waitExit(30.0));
  const std::string report = readFile(run_dir + "/report.txt");
  EXPECT_NE(report, "") << "no report in " << run_dir;
  EXPECT_EQ(report.find("finished"), std::string::npos) << report;
}

// scripts/execute_sim with another task's model ends on its own within seconds, not when
// the coordinator's start time-out (60 s) runs out: non-zero, the nodes' refusal on the
// terminal and in the report.
TEST(OtherTask, ExecuteSimEndsWithinSecondsNamingTheRefusal) {
  const Files files = Files::fromParams();
  ASSERT_FALSE(files.execute_sim.empty()) << "the .test file must set ~execute_sim";
  const std::string run_dir = std::string(setup().scratch) + "/execute_sim_run";
  const std::string out = std::string(setup().scratch) + "/execute_sim.out";
  const auto started = std::chrono::steady_clock::now();
  // `timeout` only keeps a hang from blocking the suite; the bound checked is below.
  const int status = std::system(("timeout -s INT 120 '" + files.execute_sim + "' '" + setup().task4 + "' --model '" +
                                  setup().model + "' --no-build --run-dir '" + run_dir + "' > '" + out + "' 2>&1")
                                     .c_str());
  const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const std::string printed = readFile(out);
  ASSERT_TRUE(WIFEXITED(status)) << printed;
  EXPECT_EQ(WEXITSTATUS(status), 1) << printed;
  EXPECT_LT(took_s, 45.0) << "execute_sim waited for the coordinator's start time-out:\n" << printed;
  for (const std::string& why :
       {std::string("[FATAL]"), std::string("/sequence"), std::string("vocabulary: model [move, stop], task [move]"),
        std::string("node sequence died (exit code 1)")})
    EXPECT_NE(printed.find(why), std::string::npos) << "'" << why << "' not on the terminal:\n" << printed;
  const std::string report = readFile(run_dir + "/report.txt");
  const std::string first = report.substr(0, report.find('\n'));
  EXPECT_EQ(first.rfind("failed: node /", 0), 0u) << "the first line does not say why the run failed:\n" << report;
  EXPECT_NE(first.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << report;
  EXPECT_NE(report.find("nodes that died"), std::string::npos) << report;
  EXPECT_NE(report.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << report;
  std::printf("exec_other_task: execute_sim ended after %.1f s\n", took_s);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_other_task_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
