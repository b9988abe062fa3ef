// Every model file bound to the model and the task, and another task's model with the
// same entity names refused: through pipeline::loadModel, the one
// loader, and through the real `ddace` binary (eval, inspect, path).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "ddace/common/error.h"
#include "ddace/gp/primitives.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/task/fingerprint.h"

#include "../common/file_tree.h"
#include "../common/generated_task.h"
#include "../common/run_tool.h"

using namespace ddace;
namespace fs = std::filesystem;
using ddace::test::fileBytes;
using ddace::test::generated;
using ddace::test::runTool;
using ddace::test::ToolRun;
using ddace::test::writeBytes;

namespace {

/// A Task 2 model trained with 4 robots (entity names R1..R4, G1: those of Task 4), a
/// Task 4 model, and a Task 4 test set, written once.
struct Fixture {
  fs::path root;
  std::string task2_model, task4_model, task4_test, task2_test;
  Fixture() {
    root = fs::temp_directory_path() / ("ddace_test_model_integrity_" + std::to_string(::getpid()));
    fs::remove_all(root);
    tgn::TrainOptions o;
    o.max_epochs = 2;
    task2_model = (root / "task2_model").string();
    task4_model = (root / "task4_model").string();
    pipeline::trainModel(generated("task2", 4, 1, 4), o, task2_model, nullptr);
    pipeline::trainModel(generated("task4", 4, 1), o, task4_model, nullptr);
    task4_test = (root / "task4_test").string();
    task2_test = (root / "task2_test").string();
    task::writeTaskDir(generated("task4", 2, 9), task4_test);
    task::writeTaskDir(generated("task2", 2, 9, 4), task2_test);
  }
  ~Fixture() { fs::remove_all(root); }
  /// A copy of `model` under a new name, for one edit.
  std::string copy(const std::string& model, const std::string& name) const {
    const fs::path dir = root / name;
    fs::remove_all(dir);
    fs::copy(model, dir);
    return dir.string();
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

std::string loadError(const std::string& dir) {
  try {
    pipeline::loadModel(dir);
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("NOT A ddace::Error: ") + e.what();
  }
  return "";
}

}  // namespace

TEST(ModelIntegrity, AGoodModelLoadsWithEveryFileBound) {
  const pipeline::Model m = pipeline::loadModel(fixture().task4_model);
  ASSERT_TRUE(m.primitives);
  for (const char* f : {"task.yaml", "weights.pt", "loss.csv", "primitives.yaml"})
    EXPECT_TRUE(m.sequence.info().files.count(f)) << f;
  EXPECT_EQ(m.primitives->taskFingerprint(), m.sequence.info().fingerprint);
}

TEST(ModelIntegrity, AnotherTasksPrimitiveLibraryInsideAModelIsRefused) {
  const std::string dir = fixture().copy(fixture().task4_model, "foreign_primitives");
  fs::copy_file(fs::path(fixture().task2_model) / gp::kPrimitivesFile, fs::path(dir) / gp::kPrimitivesFile,
                fs::copy_options::overwrite_existing);
  const std::string e = loadError(dir);
  EXPECT_NE(e.find("primitives.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("manifest.yaml records"), std::string::npos) << e;
}

TEST(ModelIntegrity, APrimitivesEditOfAnySizeIsRefused) {
  const std::string dir = fixture().copy(fixture().task4_model, "primitives_edit");
  std::string text = fileBytes(fs::path(dir) / gp::kPrimitivesFile);
  // The last digit of the first stored mean: far below the likelihood check's tolerance.
  const size_t means = text.find("means: [");
  const size_t comma = text.find(',', means);
  ASSERT_NE(comma, std::string::npos);
  text[comma - 1] = text[comma - 1] == '1' ? '2' : '1';
  writeBytes(fs::path(dir) / gp::kPrimitivesFile, text);
  const std::string e = loadError(dir);
  EXPECT_NE(e.find("primitives.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("edited"), std::string::npos) << e;
}

TEST(ModelIntegrity, Task2WithFourRobotsIsRefusedOnTask4) {
  const pipeline::Model m = pipeline::loadModel(fixture().task2_model);
  const task::TaskDir test = task::loadTaskDir(fixture().task4_test);
  ASSERT_EQ(m.sequence.spec().entityNames(), test.spec.entityNames());
  try {
    pipeline::modelForTask(m, fixture().task2_model, test, fixture().task4_test, false);
    FAIL() << "accepted another task's model";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << what;
    EXPECT_NE(what.find("manifest.yaml"), std::string::npos) << what;
    EXPECT_NE(what.find(fixture().task4_test), std::string::npos) << what;
  }
  EXPECT_NO_THROW(pipeline::modelForTask(m, fixture().task2_model, test, fixture().task4_test, true));
  EXPECT_NO_THROW(pipeline::modelForTask(m, fixture().task2_model, task::loadTaskDir(fixture().task2_test),
                                         fixture().task2_test, false));
}

TEST(CliModel, EvalRefusesAnotherTasksModelUnlessAllowed) {
  ToolRun r = runTool("eval " + fixture().task2_model + " " + fixture().task4_test);
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("vocabulary: model [move, stop], task [move]"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--allow-other-task"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("OSR"), std::string::npos) << "evaluated anyway: " << r.out;
  r = runTool("eval " + fixture().task2_model + " " + fixture().task4_test + " --allow-other-task");
  EXPECT_EQ(r.status, 0) << r.out;
  r = runTool("eval " + fixture().task4_model + " " + fixture().task4_test);
  EXPECT_EQ(r.status, 0) << r.out;
}

// `ddace eval MODEL DIR` takes generate's output directory (DIR/test) as validate does.
TEST(CliModel, EvalTakesAGeneratedDirectory) {
  const std::string generated_dir = (fixture().root / "task4_generated").string();
  task::writeTaskDir(task::loadTaskDir(fixture().task4_test), generated_dir + "/test");
  const ToolRun r = runTool("eval " + fixture().task4_model + " " + generated_dir);
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("OSR"), std::string::npos) << r.out;
}

TEST(CliModel, PathRefusesAnotherTasksDemonstrationsUnlessAllowed) {
  const std::string csv = (fixture().root / "paths.csv").string();
  ToolRun r = runTool("path " + fixture().task2_model + " --demos " + fixture().task4_test + " --csv " + csv);
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("goal conditions: model [R4 at G1], task [R3 at G1, R4 at G1]"), std::string::npos) << r.out;
  r = runTool("path " + fixture().task2_model + " --demos " + fixture().task4_test + " --csv " + csv +
              " --allow-other-task");
  EXPECT_EQ(r.status, 0) << r.out;
}

TEST(CliModel, InspectVerifiesEveryFile) {
  ToolRun r = runTool("inspect " + fixture().task4_model);
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("primitives.yaml"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("task fingerprint"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\n  end scene:   "), std::string::npos) << r.out;
  for (const char* f : {"primitives.yaml", "loss.csv", "task.yaml", "weights.pt", "manifest.yaml"}) {
    const std::string broken = fixture().copy(fixture().task4_model, std::string("broken_") + f);
    writeBytes(fs::path(broken) / f, fileBytes(fs::path(broken) / f) + "#\n");
    r = runTool("inspect " + broken);
    EXPECT_NE(r.status, 0) << f << ": " << r.out;
    EXPECT_NE(r.out.find(f), std::string::npos) << f << ": " << r.out;
    const std::string missing = fixture().copy(fixture().task4_model, std::string("missing_") + f);
    fs::remove(fs::path(missing) / f);
    r = runTool("inspect " + missing);
    EXPECT_NE(r.status, 0) << f << ": " << r.out;
    EXPECT_NE(r.out.find(f), std::string::npos) << f << ": " << r.out;
  }
}
