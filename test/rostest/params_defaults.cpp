// config/execution.yaml documents the parameters of the execution nodes and says every
// value in it is the node's built-in default. This test holds it to that: each key it
// sets must be one the node reads (a misspelt key would silently change nothing) and,
// except where noted below, its value must equal the default the node falls back on
// (the node classes' Params and the core structs they fill).
#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include <ros/ros.h>
#include <yaml-cpp/yaml.h>

#include "ddace/exec/coordinator.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/ros/coordinator.h"
#include "ddace/ros/execution_monitor.h"
#include "ddace/ros/gp_path.h"
#include "ddace/ros/heartbeat.h"
#include "ddace/ros/mock_robot.h"
#include "ddace/ros/path_follower.h"
#include "ddace/ros/sequence.h"

namespace {

using Defaults = std::map<std::string, YAML::Node>;

template <typename T>
YAML::Node value(const T& v) {
  return YAML::Node(v);
}

/// The defaults of a core parameter struct, under the names its visitParams() gives them
/// (the names the nodes read).
template <typename Params>
Defaults defaultsOf(Params params) {
  Defaults d;
  ddace::exec::visitParams(params, [&](const char* name, auto& field) { d[name] = value(field); });
  return d;
}

/// Every key of `section` is in `known`; those with a default equal it (numbers compared
/// as doubles, so 50 and 50.0 agree).
void expectDefaults(const YAML::Node& section, const std::string& where, const Defaults& defaults,
                    const std::set<std::string>& without_default = {}) {
  ASSERT_TRUE(section && section.IsMap()) << where << " is missing from config/execution.yaml";
  for (const auto& kv : section) {
    const std::string key = kv.first.as<std::string>();
    const auto d = defaults.find(key);
    if (d == defaults.end()) {
      EXPECT_TRUE(without_default.count(key)) << where << "/" << key << " is not a parameter the node reads";
      continue;
    }
    if (kv.second.IsMap()) continue;  // a sub-section, checked on its own
    try {
      EXPECT_DOUBLE_EQ(kv.second.as<double>(), d->second.as<double>()) << where << "/" << key;
    } catch (const YAML::Exception&) {
      EXPECT_EQ(kv.second.as<std::string>(), d->second.as<std::string>()) << where << "/" << key;
    }
  }
}

}  // namespace

TEST(ParamsDefaults, ExecutionYamlStatesTheNodesDefaults) {
  ros::NodeHandle pnh("~");
  std::string file;
  ASSERT_TRUE(pnh.getParam("execution_yaml", file));
  const YAML::Node yaml = YAML::LoadFile(file);
  using ddace::nodes::CoordinatorNode;
  using ddace::nodes::GpPathNode;
  using ddace::nodes::MockRobotNode;
  using ddace::nodes::PathFollowerNode;
  using ddace::nodes::SequenceNode;

  const CoordinatorNode::Params c;
  const ddace::exec::CoordinatorConfig cc;
  expectDefaults(yaml["coordinator"], "coordinator",
                 {{"frame_id", value(c.frame_id)},
                  {"autostart", value(c.autostart)},
                  {"start_timeout_s", value(c.start_timeout_s)},
                  {"path_points", value(c.path_points)},
                  {"timeout_check_hz", value(c.timeout_check_hz)},
                  {"resend_after_s", value(c.resend_after_s)},
                  {"state_rate_hz", value(c.state_rate_hz)},
                  {"liveness_check_hz", value(c.liveness_check_hz)},
                  {"arrival_tolerance_m", value(cc.arrival_tolerance_m)},
                  {"decision_timeout_s", value(cc.decision_timeout_s)},
                  {"path_timeout_s", value(cc.path_timeout_s)},
                  {"segment_timeout_s", value(cc.segment_timeout_s)},
                  {"segment_timeout_per_m_s", value(cc.segment_timeout_per_m_s)},
                  {"max_steps", value(cc.max_steps)},
                  {"dispatch", value(std::string(ddace::exec::toString(cc.dispatch)))},
                  {"max_replans", value(cc.max_replans)},
                  {"robot_lost_after_s", value(cc.robot_lost_after_s)}},
                 {"arrival_radius_m", "roles"});
  // roles/: the node names are the launch file's; the time-outs are CoordinatorNode's.
  const YAML::Node roles = yaml["coordinator"]["roles"];
  ASSERT_TRUE(roles && roles.IsMap());
  EXPECT_DOUBLE_EQ(roles["heartbeat_timeout_s"].as<double>(), c.heartbeat_timeout_s);
  EXPECT_DOUBLE_EQ(roles["pose_timeout_s"].as<double>(), c.pose_timeout_s);
  const double beat_hz = ddace::nodes::HeartbeatPublisher::kDefaultRateHz;

  const PathFollowerNode::Params f;
  expectDefaults(yaml["path_follower"], "path_follower",
                 {{"rate_hz", value(f.rate_hz)},
                  {"pose_timeout_s", value(f.pose_timeout_s)},
                  {"stale_fail_s", value(f.stale_fail_s)},
                  {"status_every_cycles", value(f.status_every_cycles)},
                  {"loads_ride", value(f.loads_ride)},
                  {"gains", YAML::Node()},
                  {"safety", YAML::Node()}},
                 {"robots"});
  expectDefaults(yaml["path_follower"]["safety"], "path_follower/safety", defaultsOf(ddace::exec::SafetyParams{}));
  // gains/stop_radius_m: the node's default is the task's stop radius (segments carry it).
  Defaults gains = defaultsOf(ddace::exec::FollowerGains{});
  gains.erase("stop_radius_m");
  expectDefaults(yaml["path_follower"]["gains"], "path_follower/gains", gains, {"stop_radius_m"});

  const MockRobotNode::Params m;
  Defaults mock = defaultsOf<ddace::exec::TableSimulatorParams>(m);
  mock.insert({{"frame_id", value(m.frame_id)},
               {"entities_topic", value(m.entities_topic)},
               {"publish_tf", value(m.publish_tf)},
               {"robot", YAML::Node()}});
  expectDefaults(yaml["mock_robots"], "mock_robots", mock, {"stalled", "scene_csv", "scene_demo", "scene"});
  // The simulated Hamster (exec::simulatedHamster, also `ddace eval --execution diffdrive`'s);
  // its tracking noise is the mock robots' own (eval: --noise).
  Defaults hamster = defaultsOf(ddace::exec::simulatedHamster());
  hamster.erase("position_noise_m");
  hamster.erase("yaw_noise_rad");
  expectDefaults(yaml["mock_robots"]["robot"], "mock_robots/robot", hamster, {"position_noise_m", "yaw_noise_rad"});

  const SequenceNode::Params s;
  const YAML::Node seq = yaml["sequence"];
  ASSERT_TRUE(seq && seq["policy"]);
  EXPECT_EQ(SequenceNode::parsePolicy(seq["policy"].as<std::string>(), "sequence/policy"), s.policy);
  expectDefaults(seq, "sequence",
                 {{"replay_demo", value(s.replay_demo)},
                  {"allow_other_task", value(s.allow_other_task)},
                  {"heartbeat_rate_hz", value(beat_hz)}},
                 {"policy"});

  const ddace::nodes::ExecutionMonitorNode::Params e;
  expectDefaults(yaml["execution_monitor"], "execution_monitor",
                 {{"record_bag", value(e.record_bag)},
                  {"end_launch", value(e.end_launch)},
                  {"timeout_s", value(e.timeout_s)},
                  {"collision_overlap_m", value(e.collision_overlap_m)},
                  {"collisions_fail", value(e.collisions_fail)},
                  {"heartbeat_rate_hz", value(beat_hz)}});

  const GpPathNode::Params p;
  const YAML::Node gp = yaml["gp_path"];
  ASSERT_TRUE(gp && gp["source"]);
  EXPECT_EQ(GpPathNode::parseSource(gp["source"].as<std::string>(), "gp_path/source"), p.source);
  expectDefaults(gp, "gp_path",
                 {{"frame_id", value(p.frame_id)},
                  {"points", value(p.points)},
                  {"allow_other_task", value(p.allow_other_task)},
                  {"heartbeat_rate_hz", value(beat_hz)}},
                 {"source"});
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "params_defaults");
  return RUN_ALL_TESTS();
}
