// exec::readExecutionConfig: what `ddace eval --execution diffdrive --config FILE` reads of
// an execution config, under the ROS nodes' keys.
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/exec/execution_config.h"

using namespace ddace;
using namespace ddace::exec;

namespace {

std::string shippedPath() {
  return (findRepository("", {"config"}) / "config/execution.yaml").string();
}

/// Every field of `a` equal to the same field of `b`, except those named in `except`.
template <typename Params>
void expectSameFields(Params a, Params b, const std::string& where, const std::set<std::string>& except = {}) {
  std::map<std::string, double> values;
  visitParams(b, [&](const char* name, auto& field) { values[name] = static_cast<double>(field); });
  visitParams(a, [&](const char* name, auto& field) {
    if (!except.count(name)) {
      EXPECT_EQ(static_cast<double>(field), values.at(name)) << where << "/" << name;
    }
  });
}

/// The error of parsing `text`, "" when it parses.
std::string errorOf(const std::string& text) {
  try {
    parseExecutionConfig(text, "exec.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// The shipped file states the built-in defaults, so eval with it runs as eval without it
// (the tracking noise stated for the mock robots is eval's own --noise).
TEST(ExecutionConfig, TheShippedFileIsTheBuiltInDefaults) {
  const ExecutionConfig read = readExecutionConfig(shippedPath()), defaults;
  expectSameFields(read.gains, defaults.gains, "path_follower/gains");
  expectSameFields(read.safety, defaults.safety, "path_follower/safety");
  expectSameFields(read.robot, defaults.robot, "mock_robots/robot", {"position_noise_m", "yaw_noise_rad"});
  expectSameFields(read.table, defaults.table, "mock_robots", {"status_every_cycles"});
}

TEST(ExecutionConfig, ReadsTheValuesUnderTheNodesKeys) {
  const ExecutionConfig c = parseExecutionConfig(
      "path_follower:\n  rate_hz: 50\n  gains:\n    cruise_speed_mps: 0.06\n  safety:\n    enabled: false\n"
      "    margin_m: 0.02\nmock_robots:\n  frame_id: table\n  bodies: true\n  object_damping_hz: 4\n"
      "  robot:\n    latency_s: 0.1\n    seed: 7\ncoordinator:\n  autostart: true\n",
      "exec.yaml");
  EXPECT_DOUBLE_EQ(c.gains.cruise_speed_mps, 0.06);
  EXPECT_DOUBLE_EQ(c.gains.lookahead_m, FollowerGains{}.lookahead_m) << "an absent key keeps its default";
  EXPECT_FALSE(c.safety.enabled);
  EXPECT_DOUBLE_EQ(c.safety.margin_m, 0.02);
  EXPECT_TRUE(c.table.bodies);
  EXPECT_DOUBLE_EQ(c.table.object_damping_hz, 4);
  EXPECT_DOUBLE_EQ(c.robot.latency_s, 0.1);
  EXPECT_EQ(c.robot.seed, 7u);
  // A section whose keys are all commented out is the defaults, as for the nodes.
  const ExecutionConfig empty = parseExecutionConfig("path_follower:\n  gains:\n  safety:\n", "exec.yaml");
  EXPECT_DOUBLE_EQ(empty.gains.cruise_speed_mps, FollowerGains{}.cruise_speed_mps);
}

// A typo or a wrong value is an error at its line and column, never a silent default.
TEST(ExecutionConfig, BadValuesAreNamedWhereTheyStand) {
  std::string e = errorOf("path_follower:\n  gains:\n    cruise_speed_mps: fast\n");
  EXPECT_NE(e.find("exec.yaml:3:23: path_follower/gains/cruise_speed_mps: 'fast' is not a finite number"),
            std::string::npos)
      << e;
  e = errorOf("path_follower:\n  safety:\n    margin_mm: 0.01\n");
  EXPECT_NE(e.find("exec.yaml:3:5: unknown key 'margin_mm' in path_follower/safety"), std::string::npos) << e;
  // A misspelt key of the nodes' own part of a section: eval would run the table on the
  // default (object_damping_hz 8), the node would refuse it.
  e = errorOf("mock_robots:\n  bodies: true\n  object_dampign_hz: 2\n");
  EXPECT_NE(e.find("exec.yaml:3:3: unknown key 'object_dampign_hz' in mock_robots"), std::string::npos) << e;
  e = errorOf("path_follower:\n  rate_hzz: 20\n");
  EXPECT_NE(e.find("exec.yaml:2:3: unknown key 'rate_hzz' in path_follower"), std::string::npos) << e;
  EXPECT_EQ(errorOf("path_follower:\n  robots: [R1]\n  rate_hz: 20\nmock_robots:\n  scene_demo: 1\n  stalled: [R2]\n"),
            "")
      << "the nodes' own keys are known";
  e = errorOf("mock_robots:\n  robot:\n    max_wheel_speed_mps: -1\n");
  EXPECT_NE(e.find("exec.yaml:3:5: mock_robots/robot: "), std::string::npos) << e;
  EXPECT_NE(e.find("max_wheel_speed_mps"), std::string::npos) << e;
  e = errorOf("mock_robots:\n  bodies: maybe\n");
  EXPECT_NE(e.find("exec.yaml:2:11: mock_robots/bodies: 'maybe' is not true or false"), std::string::npos) << e;
  e = errorOf("mock_robots:\n  robot:\n    seed: 9223372036854775807\n");
  EXPECT_NE(e.find("exec.yaml:3:11: mock_robots/robot/seed must be an integer in 0..9007199254740992"),
            std::string::npos)
      << e;
  e = errorOf("mock_robots:\n  bodies: false\n");
  EXPECT_NE(e.find("exec.yaml:2:11: mock_robots/bodies: false: eval's points"), std::string::npos) << e;
  e = errorOf("name: a task\nentities: []\n");
  EXPECT_NE(e.find("not an execution config"), std::string::npos) << e;
  e = errorOf("path_follower: [1, 2\n");
  EXPECT_NE(e.find("exec.yaml:"), std::string::npos) << e;
  EXPECT_THROW(readExecutionConfig("/nonexistent/execution.yaml"), Error);
}
