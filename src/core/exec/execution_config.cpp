#include "ddace/exec/execution_config.h"

#include <cstdint>
#include <limits>
#include <set>
#include <type_traits>

#include "ddace/common/file.h"
#include "ddace/common/yaml_checker.h"

namespace ddace::exec {
namespace {

/// The largest whole number a YAML number (a double) holds exactly.
constexpr long kMaxSeed = 1L << 53;

/// Reads `params`' fields (visitParams) from the mapping `map` at `where` (with
/// `only_fields`, a key that is no field is an error), then checks validate() (its error
/// at the mapping).
template <typename Params>
void readSection(YamlChecker& c, const YAML::Node& map, const std::string& where, Params& params,
                 bool only_fields = true) {
  if (!map || map.IsNull()) return;  // absent, or every key commented out: the defaults
  if (!c.expectMap(map, where)) return;
  if (only_fields) {
    std::set<std::string> names;
    visitParams(params, [&](const char* name, auto&) { names.insert(name); });
    c.onlyKeys(map, names, where);
  }
  const size_t errors = c.errors().size();
  visitParams(params, [&](const char* name, auto& field) {
    const YAML::Node v = map[name];
    if (!v) return;
    const std::string what = where + "/" + name;
    using T = std::decay_t<decltype(field)>;
    if constexpr (std::is_same_v<T, bool>) {
      c.boolean(v, what, field);
    } else if constexpr (std::is_same_v<T, int>) {
      c.integer(v, what, std::numeric_limits<int>::min(), std::numeric_limits<int>::max(), field);
    } else if constexpr (std::is_same_v<T, uint64_t>) {
      long n = 0;
      if (c.integer(v, what, 0L, kMaxSeed, n)) field = static_cast<uint64_t>(n);
    } else {
      c.number(v, what, field);
    }
  });
  if (c.errors().size() != errors) return;  // validate() would only restate them
  try {
    params.validate();
  } catch (const Error& e) {
    c.error(map, where + ": " + e.what());
  }
}

/// The names of `params`' fields (visitParams).
template <typename Params>
std::set<std::string> fieldNames(Params& params) {
  std::set<std::string> names;
  visitParams(params, [&](const char* name, auto&) { names.insert(name); });
  return names;
}

// The keys of path_follower and mock_robots that only their nodes read (src/ros/
// path_follower.cpp, mock_robot.cpp): not read here, but known, so that any other key is a
// typo. The shipped file holds every key (ExecutionConfig.TheShippedFileIsTheBuiltInDefaults
// parses it here; the params_defaults rostest holds its keys to the nodes').
const std::set<std::string> kFollowerNodeKeys = {"rate_hz",    "pose_timeout_s", "stale_fail_s", "status_every_cycles",
                                                 "loads_ride", "robots",         "task"};
const std::set<std::string> kMockRobotsNodeKeys = {"task",           "frame_id",  "publish_tf", "stalled",
                                                   "entities_topic", "scene_csv", "scene_demo", "scene"};

}  // namespace

ExecutionConfig parseExecutionConfig(const std::string& text, const std::string& file) {
  YamlChecker c(file);
  const YAML::Node root = c.parse(text);
  ExecutionConfig config;
  if (c.errors().empty() && c.expectMap(root, "an execution config (config/execution.yaml)")) {
    const YAML::Node follower = root["path_follower"], mock = root["mock_robots"];
    if (!follower && !mock)
      c.error(root, "neither path_follower nor mock_robots: not an execution config (config/execution.yaml)");
    if (follower && !follower.IsNull() && c.expectMap(follower, "path_follower")) {
      std::set<std::string> keys = kFollowerNodeKeys;
      keys.insert({"gains", "safety"});
      c.onlyKeys(follower, keys, "path_follower");
      readSection(c, follower["gains"], "path_follower/gains", config.gains);
      readSection(c, follower["safety"], "path_follower/safety", config.safety);
    }
    if (mock && !mock.IsNull() && c.expectMap(mock, "mock_robots")) {
      readSection(c, mock["robot"], "mock_robots/robot", config.robot);
      std::set<std::string> keys = fieldNames(config.table);
      keys.insert(kMockRobotsNodeKeys.begin(), kMockRobotsNodeKeys.end());
      keys.insert("robot");
      c.onlyKeys(mock, keys, "mock_robots");
      // mock_robots holds the node's own keys too: only the table's are read here.
      readSection(c, mock, "mock_robots", config.table, /*only_fields=*/false);
      if (!config.table.bodies)
        c.error(mock["bodies"],
                "mock_robots/bodies: false: eval's points (--no-bodies) run the built-in control law and take no "
                "config; a config runs the table with bodies");
    }
  }
  c.throwIfErrors();
  return config;
}

ExecutionConfig readExecutionConfig(const std::string& path) {
  return parseExecutionConfig(readTextFile(path), path);
}

}  // namespace ddace::exec
