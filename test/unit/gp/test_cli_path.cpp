// `ddace path` end to end: a model directory holding primitives.yaml (fitted here, as
// `ddace train` will do), paths on stdout and in CSV files, and clean errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ddace/gp/primitives.h"
#include "ddace/task/task_dir.h"
#include "ddace/tasks/generators.h"

#include "../common/role_tasks.h"
#include "../common/run_tool.h"

using namespace ddace;
namespace fs = std::filesystem;
using ddace::test::runTool;
using ddace::test::ToolRun;

namespace {

/// A model directory with the primitives of a generated Task 4 and its test set.
struct Model {
  std::string dir, test;
  Model() {
    const fs::path root = fs::temp_directory_path() / ("ddace_test_cli_path_" + std::to_string(::getpid()));
    fs::create_directories(root / "model");
    tasks::GeneratorOptions o;
    o.family = "task4";
    o.demos = 12;
    gp::PrimitiveLibrary::fit(tasks::generate(o)).save((root / "model" / gp::kPrimitivesFile).string());
    o.demos = 3;
    o.seed = 77;
    task::writeTaskDir(tasks::generate(o), (root / "test").string());
    dir = (root / "model").string();
    test = (root / "test").string();
    this->root = root.string();
  }
  ~Model() { fs::remove_all(root); }
  std::string root;
};

const Model& model() {
  static const Model m;
  return m;
}

}  // namespace

TEST(CliPath, PrintsARetargetedPath) {
  const ToolRun r = runTool("path " + model().dir + " --key R3:move:G1 --start 0.1,0.2 --goal 0.8,0.7 --points 5");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("# primitive R3:move:G1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("i,progress,x,y,stddev\n0,0,0.1,0.2,"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\n4,1,0.8,0.7,"), std::string::npos) << r.out;
}

TEST(CliPath, WritesCsvAndSaysWhenItFellBack) {
  const std::string csv = model().dir + "/fallback.csv";
  const ToolRun r = runTool("path " + model().dir + " --key R1:move:G1 --start 0,0 --goal 0.5,0 --csv " + csv);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("fell back to R3:move:G1"), std::string::npos) << r.out;
  std::ifstream f(csv);
  std::string line;
  int lines = 0;
  while (std::getline(f, line)) ++lines;
  EXPECT_EQ(lines, 101);  // header + 100 points
}

TEST(CliPath, DemosModeReportsFrechetPerKey) {
  const std::string csv = model().dir + "/demos.csv";
  const ToolRun r = runTool("path " + model().dir + " --demos " + model().test + " --csv " + csv);
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* key : {"R1:move:R3", "R2:move:R4", "R3:move:G1", "R4:move:G1"})
    EXPECT_NE(r.out.find(key), std::string::npos) << r.out;
  EXPECT_TRUE(fs::file_size(csv) > 1000);
}

TEST(CliPath, ListsPrimitives) {
  const ToolRun r = runTool("path " + model().dir + " --list");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("4 primitives"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("R3:move:G1                     12"), std::string::npos) << r.out;
}

TEST(CliPath, BadInputFailsWithAMessage) {
  ToolRun r = runTool("path " + model().dir + " --key R3:move:G1 --start 0.1 --goal 0.8,0.7");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("--start"), std::string::npos) << r.out;
  r = runTool("path " + model().dir + " --key R3:fly --start 0,0 --goal 1,1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("ENTITY:ACTION:TARGET"), std::string::npos) << r.out;
  r = runTool("path /nonexistent/model --key R3:move:G1 --start 0,0 --goal 1,1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("/nonexistent/model"), std::string::npos) << r.out;
  const std::string broken = model().dir + "/broken.yaml";
  std::ofstream(broken) << "format: ddace-primitives/2\ntask: x\n";
  r = runTool("path " + broken + " --key R3:move:G1 --start 0,0 --goal 1,1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find(broken), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("missing key 'entities'"), std::string::npos) << r.out;
}

TEST(CliPath, GeneratesByRoleInTheMotionsStepAndByNameWhenAsked) {
  const fs::path root = fs::path(model().root) / "line_up";
  fs::create_directories(root / "model");
  gp::PrimitiveLibrary::fit(test::lineUp(12, 1)).save((root / "model" / gp::kPrimitivesFile).string());
  task::writeTaskDir(test::lineUp(3, 2, 5), (root / "test5").string());
  ToolRun r = runTool("path " + (root / "model").string() +
                      " --key R2:move:R1 --start 0.1,0.1 --goal 0.5,0.1 --points 3 --step 2");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("# primitive robot:hamster/move/robot:hamster@2"), std::string::npos) << r.out;
  // The third robot joining the second arcs left: y above the line at mid-progress.
  const auto mid = r.out.find("\n1,0.5,");
  ASSERT_NE(mid, std::string::npos) << r.out;
  double x = 0, y = 0;
  ASSERT_EQ(std::sscanf(r.out.c_str() + mid, "\n1,0.5,%lf,%lf", &x, &y), 2) << r.out;
  EXPECT_GT(y, 0.15) << r.out;
  // Five robots from a library of three: bound by kind, each motion by its step's role.
  const std::string csv = (root / "paths.csv").string();
  r = runTool("path " + (root / "model").string() + " --demos " + (root / "test5").string() + " --csv " + csv +
              " --allow-other-task");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("R5:move:"), std::string::npos) << r.out;
  r = runTool("path " + (root / "model").string() + " --demos " + (root / "test5").string() + " --csv " + csv);
  EXPECT_EQ(r.status, 1) << r.out;
  r = runTool("path " + (root / "model").string() + " --key R2:move:R1 --start 0,0 --goal 1,0 --by-name");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("--by-name is for --demos"), std::string::npos) << r.out;
}
