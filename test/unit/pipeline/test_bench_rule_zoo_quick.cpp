// `ddace bench rule_zoo --quick`: the rule zoo benchmark end to end (both motion models,
// ideal and with bodies) on a small budget, its results printed and nothing written.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

namespace fs = std::filesystem;

TEST(BenchRuleZooQuick, BothMotionModelsIdealAndWithBodies) {
  const fs::path ddace = fs::read_symlink("/proc/self/exe").parent_path() / "ddace";
  ASSERT_TRUE(fs::exists(ddace)) << ddace;
  const fs::path repo = fs::path(::testing::TempDir()) / ("ddace_bench_rule_zoo_quick_" + std::to_string(::getpid()));
  fs::remove_all(repo);
  fs::create_directories(repo / "docs" / "bench");
  std::ofstream(repo / "package.xml") << "<package><name>ddace</name></package>\n";
  const fs::path log = repo / "out.log";
  const std::string cmd =
      "'" + ddace.string() + "' bench rule_zoo --quick --repo '" + repo.string() + "' > '" + log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  const std::string out = text.str();
  ASSERT_EQ(rc, 0) << out;
  for (const char* needle : {"`ddace bench rule_zoo --quick`", "## With bodies", "| the generators' | 2 |",
                             "| direct (touching, 4 mm, 1 cm) | 2 |", "direct paths, stops 4 mm short",
                             "paths bent around bodies, stops touching", "## Kinds of task users name"})
    EXPECT_NE(out.find(needle), std::string::npos) << needle << "\n" << out;
  // A smoke test writes no results over the shipped ones.
  EXPECT_FALSE(fs::exists(repo / "docs" / "bench" / "rule_zoo.md"));
}
