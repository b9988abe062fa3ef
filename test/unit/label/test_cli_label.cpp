// `ddace label` end to end: IN is never touched, OUT holds labelled copies that read back
// with the demonstrated steps, --strict writes nothing when anything is uncertain.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "../common/run_tool.h"
#include "ddace/label/human_motion.h"
#include "ddace/task/task_dir.h"
#include "ddace/tasks/generators.h"

namespace fs = std::filesystem;
using namespace ddace;
using ddace::test::runTool;
using ddace::test::ToolRun;

namespace {

std::string root(const std::string& name) {
  const std::string r = ::testing::TempDir() + "/ddace_cli_label_" + std::to_string(::getpid()) + "/" + name;
  fs::remove_all(r);
  fs::create_directories(r);
  return r;
}

std::map<std::string, std::string> contents(const std::string& dir) {
  std::map<std::string, std::string> files;
  for (const auto& f : fs::recursive_directory_iterator(dir))
    if (f.is_regular_file()) {
      std::ifstream in(f.path(), std::ios::binary);
      files[f.path().string()] = std::string(std::istreambuf_iterator<char>(in), {});
    }
  return files;
}

/// A task directory of fetch demonstrations moved by a person, without labels, at IN; the
/// truth is returned, and the first demonstration, labelled, is written to `example`.
task::TaskDir unlabelledTask(const std::string& in, const std::string& example, const std::string& family) {
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = 4;
  task::TaskDir truth = tasks::generate(o);
  SplitMix64 rng(5);
  for (auto& d : truth.demos) d = label::humanMotion(d, truth.spec, {}, rng);
  task::writeDemonstrationCsv(truth.demos[0], truth.spec, example);
  task::TaskDir bare = truth;
  bare.demos.erase(bare.demos.begin());
  for (auto& d : bare.demos) {
    d.has_label_columns.assign(d.entities(), false);
    d.analyze();
  }
  task::writeTaskDir(bare, in);
  truth.demos.erase(truth.demos.begin());
  return truth;
}

}  // namespace

TEST(CliLabel, LabelsACopyWithTheDemonstratedStepsAndLeavesInUntouched) {
  const std::string r = root("copy"), in = r + "/in", out = r + "/out", ex = r + "/example.csv";
  const task::TaskDir truth = unlabelledTask(in, ex, "fetch");
  const auto before = contents(in);
  const ToolRun run = runTool("label '" + in + "' --out '" + out + "' --example '" + ex + "' --strict");
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_EQ(contents(in), before);
  const task::TaskDir labelled = task::loadTaskDir(out);
  ASSERT_EQ(labelled.demos.size(), truth.demos.size());
  for (size_t i = 0; i < truth.demos.size(); ++i)
    EXPECT_TRUE(task::sameSteps(labelled.demos[i].steps, truth.demos[i].steps)) << i << "\n" << run.out;
  std::ifstream a(in + "/task.yaml"), b(out + "/task.yaml");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(a), {}), std::string(std::istreambuf_iterator<char>(b), {}));
  // Without the example every motion has the task's first action: 'move', never 'carry'.
  const std::string out2 = r + "/out2";
  ASSERT_EQ(runTool("label '" + in + "' --out '" + out2 + "'").status, 0);
  for (const auto& d : task::loadTaskDir(out2).demos)
    for (const auto& s : d.segments) EXPECT_EQ(s.token.action, "move");
}

TEST(CliLabel, KeepsTheLabelledDemonstrationsOfADirectoryThatAlsoHoldsUnlabelledOnes) {
  // Recorded partly with infer_labels: true, partly without: the unlabelled ones are
  // labelled, the labelled one is copied byte for byte, nothing is left out.
  const std::string r = root("mixed"), in = r + "/in", out = r + "/out", ex = r + "/example.csv";
  const task::TaskDir truth = unlabelledTask(in, ex, "fetch");
  const std::string kept = in + "/demos/demo_labelled.csv";
  fs::copy_file(ex, kept);
  const auto before = contents(in);
  const ToolRun run = runTool("label '" + in + "' --out '" + out + "'");
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_EQ(contents(in), before);
  EXPECT_NE(run.out.find("demo_labelled.csv: already labelled ("), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("copied as it is"), std::string::npos) << run.out;
  const task::TaskDir labelled = task::loadTaskDir(out);
  ASSERT_EQ(labelled.demos.size(), truth.demos.size() + 1);
  EXPECT_EQ(contents(out)[out + "/demos/demo_labelled.csv"], before.at(kept));
  for (const auto& d : labelled.demos) EXPECT_FALSE(d.steps.empty()) << d.source;
}

TEST(CliLabel, StrictWritesNothingWhenSomethingIsUncertain) {
  // task4 in which a person stopped R1 halfway to R3 (its rows from the middle of its first
  // motion on stay there): where it went is uncertain. (Generated robots never share a spot,
  // so a tie needs a person's mistake too.)
  const std::string r = root("strict"), in = r + "/in", out = r + "/out", ex = r + "/example.csv";
  unlabelledTask(in, ex, "task4");
  task::TaskDir dir = task::loadTaskDir(in);
  task::Demonstration& d = dir.demos[0];
  const int r1 = dir.spec.entityIndex("R1");
  size_t first = 0, last = d.rows() - 1;
  while (first < d.rows() && (d.positions[first][r1] - d.positions[0][r1]).norm() < 0.01) ++first;
  while (last > first && (d.positions[last][r1] - d.positions.back()[r1]).norm() < 0.01) --last;
  const size_t middle = (first + last) / 2;
  for (size_t k = middle; k < d.rows(); ++k) d.positions[k][r1] = d.positions[middle][r1];
  task::writeDemonstrationCsv(d, dir.spec, in + "/demos/" + std::filesystem::path(d.source).filename().string());
  const ToolRun strict = runTool("label '" + in + "' --out '" + out + "' --strict");
  EXPECT_EQ(strict.status, 1) << strict.out;
  EXPECT_NE(strict.out.find("R1 stopped halfway"), std::string::npos) << strict.out;
  EXPECT_NE(strict.out.find(".csv:"), std::string::npos) << strict.out;
  // Summarised per demonstration: the one with R1 stopped is to review, the others usable.
  const std::string name = std::filesystem::path(d.source).filename().string();
  EXPECT_NE(strict.out.find(name + ": "), std::string::npos) << strict.out;
  EXPECT_NE(strict.out.find("to review (1 token(s) listed"), std::string::npos) << strict.out;
  EXPECT_NE(strict.out.find("2 of 3 demonstrations usable; to review: " + name), std::string::npos) << strict.out;
  EXPECT_FALSE(fs::exists(out));
  const ToolRun loose = runTool("label '" + in + "' --out '" + out + "'");
  EXPECT_EQ(loose.status, 0) << loose.out;
  EXPECT_TRUE(fs::exists(out + "/task.yaml"));
}

TEST(CliLabel, RefusesToWriteIntoItsInputOrOverAnotherOnesFiles) {
  const std::string r = root("refuse"), in = r + "/in", ex = r + "/example.csv";
  unlabelledTask(in, ex, "task4");
  const auto before = contents(in);
  for (const std::string& out : {in, in + "/labelled"}) {
    const ToolRun run = runTool("label '" + in + "' --out '" + out + "'");
    EXPECT_NE(run.status, 0) << run.out;
    EXPECT_NE(run.out.find("never writes into its input"), std::string::npos) << run.out;
  }
  EXPECT_EQ(contents(in), before);
  const std::string mine = r + "/mine";
  fs::create_directories(mine);
  std::ofstream(mine + "/notes.txt") << "mine";
  const ToolRun run = runTool("label '" + in + "' --out '" + mine + "' --force");
  EXPECT_NE(run.status, 0) << run.out;
  EXPECT_TRUE(fs::exists(mine + "/notes.txt"));
  // A labelled task directory is not relabelled.
  const std::string labelled = r + "/labelled";
  tasks::GeneratorOptions o;
  o.demos = 2;
  task::writeTaskDir(tasks::generate(o), labelled);
  const ToolRun again = runTool("label '" + labelled + "' --out '" + r + "/again'");
  EXPECT_NE(again.status, 0);
  EXPECT_NE(again.out.find("already labelled"), std::string::npos) << again.out;
}

TEST(CliLabel, TheMemoryBenchTakesItsRecordingSizeThroughDdaceBench) {
  // `ddace bench label_memory --mb N` hands --mb to the benchmark (the goal's 1 GiB is
  // --mb 1024); an option with no benchmark named before it is refused and nothing runs.
  const std::string repo = root("bench_repo");
  fs::create_directories(repo + "/docs/bench");
  std::ofstream(repo + "/package.xml") << "<package><name>ddace</name></package>\n";
  const std::string md = repo + "/docs/bench/label_memory.md";
  const ToolRun none = runTool("bench --mb 1 --repo '" + repo + "'");
  EXPECT_NE(none.status, 0) << none.out;
  EXPECT_NE(none.out.find("options for a benchmark (--mb) need exactly one benchmark named"), std::string::npos)
      << none.out;
  EXPECT_FALSE(fs::exists(md));
  const ToolRun bad = runTool("bench label_memory --mb 0 --repo '" + repo + "'");
  EXPECT_NE(bad.status, 0) << bad.out;
  EXPECT_NE(bad.out.find("--mb must be a size in MB"), std::string::npos) << bad.out;
  // --repo=DIR is ddace bench's own, wherever it stands (as --repo DIR above).
  runTool("bench label_memory --repo='" + repo + "' --mb 1");  // its goal is for long recordings
  std::ifstream in(md);
  const std::string text{std::istreambuf_iterator<char>(in), {}};
  EXPECT_NE(text.find("Written by `ddace bench label_memory --mb 1`"), std::string::npos) << text;
  const ToolRun list = runTool("bench label_memory --mb 1 --list");
  EXPECT_NE(list.status, 0) << list.out;
  EXPECT_NE(list.out.find("would be lost"), std::string::npos) << list.out;
}

TEST(CliLabel, TheStylesBenchRunsQuickly) {
  // `ddace bench label_styles --quick`: a few families and styles, the report on stdout,
  // no results file written; each cell's accuracy and the doubt table are there.
  const std::string repo = root("styles_repo");
  fs::create_directories(repo + "/docs/bench");
  std::ofstream(repo + "/package.xml") << "<package><name>ddace</name></package>\n";
  const ToolRun run = runTool("bench label_styles --quick --repo '" + repo + "'");
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("| zoo:87 |"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("| every style |"), std::string::npos) << run.out;
  EXPECT_FALSE(fs::exists(repo + "/docs/bench/label_styles.md"));
  const ToolRun bad = runTool("bench label_styles --demos 1 --repo '" + repo + "'");
  EXPECT_NE(bad.status, 0) << bad.out;
  EXPECT_NE(bad.out.find("--demos must be 2..200"), std::string::npos) << bad.out;
}
