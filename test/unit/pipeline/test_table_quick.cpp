// `ddace table --quick`: the whole Table 2 command end to end (generate, train every
// variant, evaluate, plot, write results.md), on a small budget.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

namespace fs = std::filesystem;

TEST(TableQuick, WritesResultsAndEveryFigure) {
  // The ddace tool is built next to this test binary (devel/lib/ddace).
  const fs::path ddace = fs::read_symlink("/proc/self/exe").parent_path() / "ddace";
  ASSERT_TRUE(fs::exists(ddace)) << ddace;
  const fs::path out = fs::path(::testing::TempDir()) / ("ddace_table_quick_" + std::to_string(::getpid()));
  fs::remove_all(out);
  // The table pins libtorch's kernels to AVX2 whatever the caller's environment says: a
  // model trained alone with AVX2 kernels must equal the table's (below).
  const std::string cmd = "ATEN_CPU_CAPABILITY=default '" + ddace.string() + "' table --quick --out '" +
                          (out / "run").string() + "' --docs '" + (out / "docs").string() + "' > '" +
                          (out.string() + ".log") + "' 2>&1";
  fs::create_directories(out);
  const int rc = std::system(cmd.c_str());
  std::ifstream log(out.string() + ".log");
  std::stringstream log_text;
  log_text << log.rdbuf();
  ASSERT_EQ(rc, 0) << log_text.str();

  std::ifstream md((out / "docs" / "results.md").string());
  ASSERT_TRUE(md) << "no results.md";
  std::stringstream text;
  text << md.rdbuf();
  const std::string results = text.str();
  for (const char* needle : {"| task1 | DDACE (the paper's network) |",
                             "| task1 | DDACE, scene network (default) |",
                             "| task4 | w/o spectral clustering |",
                             "| task2 | GNN |",
                             "| task3 | LLM (GPT-5.2) |",
                             "0 / 0.3 / 0.59 / 0",
                             "## Few-shot, every family",
                             "| fetch | 3 demos | GNN |",
                             "## Human-timed demonstrations",
                             "| task4 | human-timed, 3 demos |",
                             "## Imperfect demonstrations",
                             "## Rule zoo",
                             "| 3 | 2 |",
                             "### Kinds of task users name",
                             "### Rule zoo with bodies",
                             "| the generators' | 2 |",
                             "| direct (touching, 4 mm, 1 cm) | 2 |",
                             "### Other team sizes",
                             "| 2.0x |",
                             "--quick"})
    EXPECT_NE(results.find(needle), std::string::npos) << needle;
  // The default network's few-shot and human-timed models also ran in closed loop.
  const size_t closed = results.find("## Closed loop: simulated differential-drive robots");
  ASSERT_NE(closed, std::string::npos);
  EXPECT_NE(results.find("| fetch | 3 demos |", closed), std::string::npos) << results.substr(closed);
  EXPECT_NE(results.find("| task4 | human-timed, 3 demos |", closed), std::string::npos) << results.substr(closed);
  // ... and with bodies, with and without the safety filter, every trial's collisions judged.
  const size_t bodies = results.find("## Bodies");
  ASSERT_NE(bodies, std::string::npos);
  EXPECT_NE(results.find("| fetch | 3 demos |", bodies), std::string::npos) << results.substr(bodies);
  EXPECT_NE(results.find("Zero collisions on every family", bodies), std::string::npos) << results.substr(bodies);
  for (const char* file : {"fetch-3-scene-bodies.json", "fetch-3-scene-bodies-unfiltered.json"}) {
    std::ifstream json((out / "run" / "eval" / file).string());
    std::stringstream json_text;
    json_text << json.rdbuf();
    EXPECT_NE(json_text.str().find("\"collisions\""), std::string::npos) << file;
  }
  // Labels inferred from motion: both trainings with every training seed (a row each), the
  // OSR columns their mean and range, and the difference inferred - true with its error.
  const size_t labels = results.find("## Labels inferred from motion");
  ASSERT_NE(labels, std::string::npos);
  EXPECT_NE(results.find("training seeds 1-2", labels), std::string::npos) << results.substr(labels);
  EXPECT_NE(results.find(" ± ", labels), std::string::npos) << results.substr(labels);
  for (const char* row : {"task4-motion-3-true-scene-seed1.txt", "task4-motion-3-inferred-scene-seed2.txt"})
    EXPECT_TRUE(fs::exists(out / "run" / "rows" / row)) << row;
  std::ifstream closed_json((out / "run" / "eval" / "fetch-3-scene-diffdrive.json").string());
  std::stringstream closed_text;
  closed_text << closed_json.rdbuf();
  EXPECT_NE(closed_text.str().find("diffdrive"), std::string::npos) << "no closed-loop evaluation of fetch-3-scene";
  for (const char* fig :
       {"loss_fig4.png", "loss_task2_robots.png", "loss_task3_actions.png", "overlay_task1.png", "overlay_task4.png"})
    EXPECT_TRUE(fs::exists(out / "docs" / "figures" / fig)) << fig;
  // The wall time against the 20-minute goal is written as a bench result.
  std::ifstream bench((out / "docs" / "bench" / "table.md").string());
  std::stringstream bench_text;
  bench_text << bench.rdbuf();
  EXPECT_NE(bench_text.str().find("| `ddace table --quick` wall time |"), std::string::npos) << bench_text.str();

  // Models train side by side (one process each, --jobs defaults to the cores): each must
  // equal the same model trained alone.
  const fs::path alone = out / "alone";
  const std::string train = "ATEN_CPU_CAPABILITY=avx2 '" + ddace.string() + "' train '" +
                            (out / "run" / "data" / "task4" / "train").string() + "' --out '" + alone.string() +
                            "' --variant gnn --epochs 40 --seed 1 --quiet > '" + out.string() + "_alone.log' 2>&1";
  ASSERT_EQ(std::system(train.c_str()), 0) << train;
  auto lossColumns = [](const fs::path& model) {  // epoch, loss, accuracy: not the wall time
    std::ifstream in((model / "loss.csv").string());
    std::string line, text;
    while (std::getline(in, line)) text += line.substr(0, line.rfind(',')) + "\n";
    return text;
  };
  const std::string in_table = lossColumns(out / "run" / "models" / "task4-gnn");
  EXPECT_GT(in_table.size(), 100u);
  EXPECT_EQ(in_table, lossColumns(alone));
  fs::remove_all(out);
}
