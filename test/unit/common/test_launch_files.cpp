// What the execution launch files promise a user, read by roslaunch's own loader (nothing
// is started): with rviz the launch stays up on the run's final state until rviz is
// closed; a dead coordinator ends the launch.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "launch_config.h"

namespace {

using ddace::test::loadLaunches;
using ddace::test::namespacesWork;

const std::vector<std::string> kExecutionLaunches{"execute_sim.launch", "execute_real.launch"};

}  // namespace

TEST(LaunchFiles, WithRvizTheLaunchStaysOnTheFinalStateUntilRvizIsClosed) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  std::string out;
  for (const auto& [file, config] : loadLaunches(kExecutionLaunches, "task:=t model:=m rviz:=true", false, &out)) {
    ASSERT_EQ(config.refused, "") << file;
    // The monitor writes the record and leaves roslaunch running; closing rviz ends it.
    EXPECT_EQ(config.params.count("/execution_monitor/end_launch"), 1u) << file << "\n" << out;
    EXPECT_EQ(config.params.at("/execution_monitor/end_launch"), "False") << file;
    const ddace::test::LaunchNode* rviz = config.node("rviz");
    ASSERT_NE(rviz, nullptr) << file << "\n" << out;
    EXPECT_TRUE(rviz->required) << file << ": closing rviz must end the launch";
  }
  const auto headless = loadLaunches(kExecutionLaunches, "task:=t model:=m", false, &out);
  EXPECT_EQ(headless.size(), kExecutionLaunches.size()) << out;
  for (const auto& [file, config] : headless) {
    ASSERT_EQ(config.refused, "") << file;
    EXPECT_EQ(config.node("rviz"), nullptr) << file;
    // Without rviz the monitor ends the launch once the record is written.
    EXPECT_EQ(config.params.count("/execution_monitor/end_launch"), 1u) << file << "\n" << out;
    EXPECT_EQ(config.params.at("/execution_monitor/end_launch"), "True") << file;
    const ddace::test::LaunchNode* coordinator = config.node("coordinator");
    ASSERT_NE(coordinator, nullptr) << file << "\n" << out;
    EXPECT_TRUE(coordinator->required) << file << ": nothing else ends a run whose nodes died";
  }
}
