// `ddace generate` and `ddace validate` end to end: nothing a user owns is lost, every
// failure is named and exits non-zero, validate goes on past a directory it cannot read.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "../common/run_tool.h"

namespace fs = std::filesystem;
using ddace::test::runTool;
using ddace::test::ToolRun;

namespace {

std::string root() {
  const std::string r = ::testing::TempDir() + "/ddace_cli_task_" + std::to_string(::getpid());
  fs::create_directories(r);
  return r;
}

std::string read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace

TEST(CliGenerate, RefusesADirectoryHoldingARecordingAndAHandWrittenTaskYamlEvenWithForce) {
  const std::string out = root() + "/user";
  fs::create_directories(out + "/demos");
  const std::string yaml = "format: ddace-task/1\n# mine\nentities: [{name: R1, kind: robot}]\n";
  const std::string csv = "t,R1.x,R1.y\n0,0.1,0.1\n";
  std::ofstream(out + "/task.yaml") << yaml;
  std::ofstream(out + "/demos/my_recording.csv") << csv;
  for (const std::string force : {"", " --force"}) {
    const ToolRun r = runTool("generate task1 --out '" + out + "' --train 2 --test 1" + force);
    EXPECT_NE(r.status, 0) << r.out;
    EXPECT_NE(r.out.find(out + "/demos/my_recording.csv (not written by ddace generate)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(out + "/task.yaml (not written by ddace generate)"), std::string::npos) << r.out;
    EXPECT_EQ(read(out + "/task.yaml"), yaml);
    EXPECT_EQ(read(out + "/demos/my_recording.csv"), csv);
  }
}

TEST(CliGenerate, ReplacesItsOwnOutputOnlyWithForceAndLeavesNoStaleFile) {
  const std::string out = root() + "/own";
  ToolRun r = runTool("generate task4 --out '" + out + "' --train 5 --test 1");
  ASSERT_EQ(r.status, 0) << r.out;
  r = runTool("generate task4 --out '" + out + "' --train 2 --test 1");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("--force replaces it"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(out + "/train/demos/demo_004.csv"));
  r = runTool("generate task4 --out '" + out + "' --train 2 --test 1 --force");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_FALSE(fs::exists(out + "/train/demos/demo_004.csv"));
  EXPECT_TRUE(fs::exists(out + "/train/demos/demo_001.csv"));
  // A model trained into the output (as `ddace train --out DIR/model` would) is not generate's.
  fs::create_directories(out + "/model");
  std::ofstream(out + "/model/weights.pt") << "w";
  r = runTool("generate task4 --out '" + out + "' --train 2 --test 1 --force");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find(out + "/model/weights.pt (not written by ddace generate)"), std::string::npos) << r.out;
  EXPECT_EQ(read(out + "/model/weights.pt"), "w");
}

TEST(CliGenerate, AnOutputThatCannotBeWrittenIsAnError) {
  ToolRun r = runTool("generate task4 --out /dev/full --train 1 --test 1");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("/dev/full: exists and is not a directory"), std::string::npos) << r.out;
  r = runTool("generate task4 --out /proc/ddace_not_writable --train 1 --test 1");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_EQ(r.out.find("generated"), std::string::npos) << r.out;
}

TEST(CliGenerate, OnsetJitterIsMergedBackAndValidateSaysWhere) {
  const std::string out = root() + "/onset";
  ToolRun r = runTool("generate task4 --out '" + out + "' --train 3 --test 1 --onset-jitter 0.9");
  ASSERT_EQ(r.status, 0) << r.out;
  r = runTool("validate '" + out + "'");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("every demonstration has the same 2 steps"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(out + "/train/demos/demo_000.csv:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("s after the step's first token (line "), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("test/demos/demo_000.csv:"), std::string::npos) << r.out;  // the test set is clean
  r = runTool("generate task4 --out '" + out + "2' --onset-jitter 1");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("--onset-jitter 1 is out of range"), std::string::npos) << r.out;
}

// A demonstration whose steps are the others' but for one mislabelled token is a labelling
// slip: validate names the file, the step and both tokens, and still lists the common steps.
TEST(CliValidate, SaysWhereALabellingSlipIs) {
  const std::string out = root() + "/slips";
  ToolRun r = runTool("generate task4 --out '" + out + "' --train 10 --test 1 --mislabel 0.1");
  ASSERT_EQ(r.status, 0) << r.out;
  r = runTool("validate '" + out + "/train'");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("every demonstration has the same 2 steps but for 1 labelling slip:"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find(" where the others have R"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("step 2: [R3:move:G1 R4:move:G1]"), std::string::npos) << r.out;
}

TEST(CliValidate, ADirectoryThatCannotBeReadIsOneErrorAndTheRestIsValidated) {
  const std::string base = root();
  const std::string good = base + "/good", loop = base + "/loop";
  ASSERT_EQ(runTool("generate task4 --out '" + good + "' --train 2 --test 1").status, 0);
  fs::remove(loop);
  fs::create_symlink(loop, loop);  // a symlink loop
  const ToolRun r = runTool("validate '" + loop + "' '" + good + "/train'");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find(loop + ": 1 error(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("symbolic links"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(good + "/train: task 'task4_trajectory_shape'"), std::string::npos) << r.out;
}
