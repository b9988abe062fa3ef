// `ddace init` end to end: a task of one's own whose files validate and parse with the
// readers of the nodes that read them, for exactly the entities named (nothing of the
// shipped Task 4 template), never replacing a file. And the front end's slips: "did you
// mean" for a subcommand or an option.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "../common/run_tool.h"
#include "ddace/hamster/config.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/recorder.h"
#include "ddace/vision/tracker.h"

namespace fs = std::filesystem;
using namespace ddace;
using ddace::test::runTool;
using ddace::test::ToolRun;

namespace {

std::string scratch(const std::string& name) {
  const std::string r = ::testing::TempDir() + "/ddace_cli_init_" + std::to_string(::getpid()) + "/" + name;
  fs::remove_all(r);
  fs::create_directories(fs::path(r).parent_path());
  return r;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(CliInit, WritesAValidTaskOfExactlyTheNamedEntities) {
  const std::string dir = scratch("fetch two");  // a space: paths are quoted where they are written
  const ToolRun r = runTool("init '" + dir + "' --robots A1,A2 --objects Box --goals Home");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find(": 2 robots, 1 object, 1 goal, no goal condition"), std::string::npos) << r.out;

  const ToolRun v = runTool("validate '" + dir + "'");
  EXPECT_EQ(v.status, 0) << v.out;
  EXPECT_NE(v.out.find("A1 robot, A2 robot, Home goal, Box object"), std::string::npos) << v.out;

  // Each file parses with the reader of the node that reads it.
  const std::string config = dir + "/config/";
  const vision::MarkerConfig markers = vision::loadMarkerConfig(config + "markers.yaml");
  const vision::RecorderConfig recorder = vision::loadRecorderConfig(config + "recorder.yaml", markers);
  const hamster::BridgeConfig hamsters = hamster::loadBridgeConfig(config + "hamsters.yaml");
  EXPECT_EQ(recorder.spec.entityNames(), (std::vector<std::string>{"A1", "A2", "Home", "Box"}));
  EXPECT_TRUE(recorder.spec.goal_conditions.empty()) << "a goal condition the user did not write";
  EXPECT_EQ(fs::path(recorder.output_dir), fs::path(dir));
  ASSERT_EQ(hamsters.robots.size(), 2u);
  EXPECT_EQ(hamsters.robots[0].name, "A1");
  EXPECT_EQ(hamsters.robots[1].name, "A2");
  // task.yaml is the one the recorder writes from these files: recording into DIR is accepted.
  const task::TaskSpec written = task::readTaskYaml(dir + "/task.yaml");
  EXPECT_EQ(task::taskYamlText(written), task::taskYamlText(recorder.spec));
  EXPECT_NO_THROW(vision::DemoRecorder(recorder.spec, recorder.output_dir));
  // Nothing of the shipped Task 4 template. The directory's own path is left out: a
  // scratch directory's random name may hold "R3".
  for (const char* file : {"/task.yaml", "/config/markers.yaml", "/config/recorder.yaml", "/config/hamsters.yaml"}) {
    std::string text = readAll(dir + file);
    for (const std::string& path : {dir, fs::path(dir).lexically_normal().string()})
      for (size_t at; (at = text.find(path)) != std::string::npos;) text.erase(at, path.size());
    for (const char* task4 : {"task4", "R3", "R4", "G1"}) EXPECT_EQ(text.find(task4), std::string::npos) << file;
  }
  EXPECT_NE(readAll(config + "hamsters.yaml").find("FILL IN"), std::string::npos);
}

TEST(CliInit, NeverReplacesAFileAndRefusesBadNames) {
  const std::string dir = scratch("again");
  ASSERT_EQ(runTool("init '" + dir + "' --robots R1 --goals G1").status, 0);
  std::ofstream(dir + "/config/markers.yaml", std::ios::app) << "# my edit\n";
  const std::string mine = readAll(dir + "/config/markers.yaml");
  const ToolRun again = runTool("init '" + dir + "' --robots R1,R2");
  EXPECT_NE(again.status, 0);
  EXPECT_NE(again.out.find("markers.yaml"), std::string::npos) << again.out;
  EXPECT_NE(again.out.find("never replaces"), std::string::npos) << again.out;
  EXPECT_EQ(readAll(dir + "/config/markers.yaml"), mine);

  const ToolRun twice = runTool("init '" + scratch("twice") + "' --robots R1 --goals R1");
  EXPECT_NE(twice.status, 0);
  EXPECT_NE(twice.out.find("'R1' is named twice"), std::string::npos) << twice.out;
  const ToolRun bad = runTool("init '" + scratch("bad") + "' --robots 1R");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.out.find("'1R' is not an entity name"), std::string::npos) << bad.out;
  EXPECT_FALSE(fs::exists(scratch("bad") + "/task.yaml"));
}

// Demonstrations recorded with infer_labels: false have no step: validate says so and what to
// run, train refuses them naming each file (a demonstration without a step would teach
// "END at once"), before writing anything.
TEST(CliInit, UnlabelledDemonstrationsAreNamedByValidateAndRefusedByTrain) {
  const std::string dir = scratch("unlabelled");
  ASSERT_EQ(runTool("init '" + dir + "' --robots R1 --goals G1").status, 0);
  fs::create_directories(dir + "/demos");
  std::ofstream(dir + "/demos/demo_000.csv") << "t,R1.x,R1.y,R1.action,R1.target,G1.x,G1.y\n"
                                                "0.0,0.1,0.1,,,0.5,0.5\n0.5,0.3,0.3,,,0.5,0.5\n1.0,0.5,0.5,,,0.5,0.5\n";
  const ToolRun v = runTool("validate '" + dir + "'");
  EXPECT_EQ(v.status, 0) << v.out;
  EXPECT_NE(v.out.find("1 of 1 demonstrations have no labelled step"), std::string::npos) << v.out;
  EXPECT_NE(v.out.find("`ddace label " + dir + " --out DIR`"), std::string::npos) << v.out;
  const std::string model = scratch("unlabelled-model");
  const ToolRun t = runTool("train '" + dir + "' --out '" + model + "'");
  EXPECT_NE(t.status, 0);
  EXPECT_NE(t.out.find(dir + "/demos/demo_000.csv: no labelled step"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("`ddace label " + dir + " --out DIR`"), std::string::npos) << t.out;
  EXPECT_FALSE(fs::exists(model));
  // With a labelled demonstration beside it, ddace label labels the one and keeps the other.
  std::ofstream(dir + "/demos/demo_001.csv") << "t,R1.x,R1.y,R1.action,R1.target,G1.x,G1.y\n"
                                                "0.0,0.1,0.1,move,G1,0.5,0.5\n0.5,0.3,0.3,move,G1,0.5,0.5\n"
                                                "1.0,0.5,0.5,,,0.5,0.5\n";
  const ToolRun mixed = runTool("train '" + dir + "' --out '" + model + "'");
  EXPECT_NE(mixed.status, 0);
  EXPECT_NE(mixed.out.find("demo_000.csv: no labelled step"), std::string::npos) << mixed.out;
  EXPECT_EQ(mixed.out.find("demo_001.csv"), std::string::npos) << mixed.out;
  EXPECT_NE(mixed.out.find("`ddace label " + dir + " --out DIR` infers their labels and copies the labelled"),
            std::string::npos)
      << mixed.out;
}

TEST(CliInit, ASlipInASubcommandOrOptionGetsASuggestion) {
  const ToolRun sub = runTool("trian x");
  EXPECT_EQ(sub.status, 2);
  EXPECT_NE(sub.out.find("unknown subcommand 'trian' (did you mean train?)"), std::string::npos) << sub.out;
  const ToolRun opt = runTool("init " + scratch("opt") + " --robot R1");
  EXPECT_NE(opt.status, 0);
  EXPECT_NE(opt.out.find("unknown option --robot (did you mean --robots?)"), std::string::npos) << opt.out;
  // A single error stays on the line that names the subcommand.
  const ToolRun missing = runTool("label " + scratch("missing"));
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.out.find("ddace label: error: missing required option --out"), std::string::npos) << missing.out;
  // Another word is not a slip: no suggestion.
  const ToolRun other = runTool("frobnicate");
  EXPECT_EQ(other.out.find("did you mean"), std::string::npos) << other.out;
}
