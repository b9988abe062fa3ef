#include "ddace/task/task_spec.h"

#include <algorithm>
#include <cctype>
#include <optional>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "ddace/common/file.h"
#include "ddace/common/yaml_checker.h"
#include "number.h"

namespace ddace::task {

const char* toString(EntityKind kind) {
  switch (kind) {
    case EntityKind::Robot:
      return "robot";
    case EntityKind::Object:
      return "object";
    case EntityKind::Goal:
      return "goal";
  }
  return "robot";
}

std::optional<EntityKind> entityKindFromString(const std::string& s) {
  if (s == "robot") return EntityKind::Robot;
  if (s == "object") return EntityKind::Object;
  if (s == "goal") return EntityKind::Goal;
  return std::nullopt;
}

bool isValidName(const std::string& name) {
  if (name.empty() || !std::isalpha(static_cast<unsigned char>(name[0]))) return false;
  for (char c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  return true;
}

int TaskSpec::entityIndex(const std::string& name) const {
  for (size_t i = 0; i < entities.size(); ++i)
    if (entities[i].name == name) return static_cast<int>(i);
  return -1;
}

bool TaskSpec::allowsAction(const std::string& action) const {
  if (!actions_declared) return true;
  for (const auto& a : actions)
    if (a == action) return true;
  return false;
}

std::vector<std::string> TaskSpec::entityNames() const {
  std::vector<std::string> names;
  for (const auto& e : entities) names.push_back(e.name);
  return names;
}

Footprint footprint(const Entity& e) {
  Footprint f;
  switch (e.kind) {
    case EntityKind::Robot:
      f = {kDefaultRobotRadius, true};
      break;
    case EntityKind::Object:
      f = {kDefaultObjectRadius, true};
      break;
    case EntityKind::Goal:
      f = {kDefaultGoalRadius, false};
      break;
  }
  if (e.radius_m) f.radius_m = *e.radius_m;
  if (e.obstacle) f.obstacle = *e.obstacle;
  return f;
}

Footprint TaskSpec::footprint(int i) const {
  return task::footprint(entities.at(static_cast<size_t>(i)));
}

double TaskSpec::contactDistance(int a, int b) const {
  const Footprint fa = footprint(a), fb = footprint(b);
  return fa.obstacle && fb.obstacle ? fa.radius_m + fb.radius_m : 0.0;
}

bool ActionRule::matches(const Entity& mover, const Entity& target, int load_kind) const {
  if (mover_kind && *mover_kind != mover.kind) return false;
  if (!mover_type.empty() && mover_type != mover.type) return false;
  if (target_kind && *target_kind != target.kind) return false;
  if (!target_type.empty() && target_type != target.type) return false;
  switch (load) {
    case Load::Any:
      return true;
    case Load::None:
      return load_kind == 0;
    case Load::Carries:
      return load_kind == 1;
    case Load::Carried:
      return load_kind == 2;
  }
  return false;
}

const char* toString(ActionRule::Load load) {
  switch (load) {
    case ActionRule::Load::Any:
      return "";
    case ActionRule::Load::None:
      return "none";
    case ActionRule::Load::Carries:
      return "carries";
    case ActionRule::Load::Carried:
      return "carried";
  }
  return "";
}

namespace {

/// "KIND" or "KIND/TYPE" (the type is the rest: free text) of an action rule's mover or target.
bool parseKindAndType(YamlChecker& c, const YAML::Node& node, const char* what, std::optional<EntityKind>& kind,
                      std::string& type) {
  std::string text;
  if (!c.text(node, what, text)) return false;
  const size_t slash = text.find('/');
  const auto k = entityKindFromString(text.substr(0, slash));
  if (!k) {
    c.error(node, std::string(what) + " '" + text + "' must be robot, object or goal, optionally with /TYPE");
    return false;
  }
  kind = *k;
  if (slash != std::string::npos) {
    type = text.substr(slash + 1);
    if (type.empty()) {
      c.error(node, std::string(what) + " '" + text + "': a type after '/' must not be empty");
      return false;
    }
  }
  return true;
}

/// One entity of task.yaml's list (nullopt after an error said by `c`); `names` collects the
/// names seen so far, to refuse a duplicate.
std::optional<Entity> parseEntity(YamlChecker& c, const YAML::Node& node, std::set<std::string>& names) {
  c.onlyKeys(node, {"name", "kind", "type", "radius", "obstacle"}, "an entity");
  Entity e;
  bool ok = true;
  if (!node["name"]) {
    c.error(node, "entity without 'name'");
    ok = false;
  } else if (c.scalar(node["name"], "entity name", e.name)) {
    if (!isValidName(e.name)) {
      c.error(node["name"], "entity name '" + e.name + "' must match [A-Za-z][A-Za-z0-9_]*");
      ok = false;
    } else if (!names.insert(e.name).second) {
      c.error(node["name"], "duplicate entity name '" + e.name + "'");
      ok = false;
    }
  } else {
    ok = false;
  }
  std::string kind;
  if (!node["kind"]) {
    c.error(node, "entity '" + e.name + "' without 'kind' (robot, object or goal)");
    ok = false;
  } else if (c.scalar(node["kind"], "kind", kind)) {
    auto k = entityKindFromString(kind);
    if (!k) {
      c.error(node["kind"], "unknown kind '" + kind + "' (expected robot, object or goal)");
      ok = false;
    } else {
      e.kind = *k;
    }
  }
  // Free text, but text: taskYamlText writes it back unchanged (found by fuzzing).
  if (node["type"] && !c.text(node["type"], "type", e.type)) ok = false;
  if (node["radius"]) {
    double r = 0;
    if (c.positive(node["radius"], "radius", r)) e.radius_m = r;
    else ok = false;
  }
  if (node["obstacle"]) {
    bool b = true;
    if (c.boolean(node["obstacle"], "obstacle", b)) e.obstacle = b;
    else ok = false;
  }
  if (!ok) return std::nullopt;
  return e;
}

/// task.yaml's entities; returns their names (for the goal conditions).
std::set<std::string> parseEntities(YamlChecker& c, const YAML::Node& root, TaskSpec& spec) {
  std::set<std::string> names;
  if (!c.required(root, "entities")) return names;  // said by required()
  if (!root["entities"].IsSequence() || root["entities"].size() == 0) {
    c.error(root["entities"], "entities must be a non-empty list of {name, kind, type}");
    return names;
  }
  for (const auto& node : root["entities"]) {
    if (!node.IsMap()) {
      c.error(node, "an entity must be a mapping {name, kind, type}");
      continue;
    }
    if (auto e = parseEntity(c, node, names)) spec.entities.push_back(*e);
  }
  return names;
}

void parseActions(YamlChecker& c, const YAML::Node& root, TaskSpec& spec) {
  if (!root["actions"]) return;
  spec.actions_declared = true;
  if (!root["actions"].IsSequence()) {
    c.error(root["actions"], "actions must be a list of words");
    return;
  }
  std::set<std::string> seen;
  for (const auto& node : root["actions"]) {
    std::string a;
    if (!c.scalar(node, "action", a)) continue;
    if (!isValidName(a)) {
      c.error(node, "action '" + a + "' must match [A-Za-z][A-Za-z0-9_]*");
    } else if (a == "idle") {
      c.error(node, "'idle' is reserved for no action and cannot be listed in actions");
    } else if (!seen.insert(a).second) {
      c.error(node, "duplicate action '" + a + "'");
    } else {
      spec.actions.push_back(a);
    }
  }
}

/// One goal condition {entity, at, tolerance} (nullopt after an error said by `c`).
std::optional<GoalCondition> parseGoalCondition(YamlChecker& c, const YAML::Node& node,
                                                const std::set<std::string>& names) {
  c.onlyKeys(node, {"entity", "at", "tolerance"}, "a goal condition");
  GoalCondition g;
  bool ok = true;
  for (const char* key : {"entity", "at"}) {
    std::string value;
    if (!node[key]) {
      c.error(node, std::string("goal condition without '") + key + "'");
      ok = false;
    } else if (c.scalar(node[key], key, value)) {
      if (!names.count(value)) {
        c.error(node[key], "goal condition names unknown entity '" + value + "'");
        ok = false;
      }
      (std::string(key) == "entity" ? g.entity : g.at) = value;
    } else {
      ok = false;
    }
  }
  if (node["tolerance"]) {
    if (!c.number(node["tolerance"], "tolerance", g.tolerance)) {
      ok = false;
    } else if (g.tolerance <= 0) {
      c.error(node["tolerance"], "tolerance must be positive (metres)");
      ok = false;
    }
  }
  if (!ok) return std::nullopt;
  return g;
}

void parseGoalConditions(YamlChecker& c, const YAML::Node& root, const std::set<std::string>& names, TaskSpec& spec) {
  if (!root["goal_conditions"]) return;
  if (!root["goal_conditions"].IsSequence()) {
    c.error(root["goal_conditions"], "goal_conditions must be a list of {entity, at, tolerance}");
    return;
  }
  for (const auto& node : root["goal_conditions"]) {
    if (!node.IsMap()) {
      c.error(node, "a goal condition must be a mapping {entity, at, tolerance}");
      continue;
    }
    if (auto g = parseGoalCondition(c, node, names)) spec.goal_conditions.push_back(*g);
  }
}

/// One action rule {mover, target, load, action} (nullopt after an error said by `c`).
std::optional<ActionRule> parseActionRule(YamlChecker& c, const YAML::Node& node, const TaskSpec& spec) {
  c.onlyKeys(node, {"mover", "target", "load", "action"}, "an action rule");
  ActionRule rule;
  bool ok = true;
  if (node["mover"]) {
    ok = parseKindAndType(c, node["mover"], "mover", rule.mover_kind, rule.mover_type) && ok;
    if (ok && rule.mover_kind == EntityKind::Goal) {
      c.error(node["mover"], "a goal does not act: mover must be robot or object");
      ok = false;
    }
  }
  if (node["target"]) ok = parseKindAndType(c, node["target"], "target", rule.target_kind, rule.target_type) && ok;
  if (node["load"]) {
    std::string load;
    if (!c.scalar(node["load"], "load", load)) ok = false;
    else if (load == "none") rule.load = ActionRule::Load::None;
    else if (load == "carries") rule.load = ActionRule::Load::Carries;
    else if (load == "carried") rule.load = ActionRule::Load::Carried;
    else {
      c.error(node["load"], "load '" + load + "' must be none, carries or carried");
      ok = false;
    }
  }
  if (!node["action"]) {
    c.error(node, "action rule without 'action'");
    ok = false;
  } else if (c.scalar(node["action"], "action", rule.action)) {
    if (!isValidName(rule.action) || rule.action == "idle") {
      c.error(node["action"], "action '" + rule.action + "' must match [A-Za-z][A-Za-z0-9_]* and not be idle");
      ok = false;
    } else if (!spec.allowsAction(rule.action)) {
      c.error(node["action"], "action '" + rule.action + "' is not in the task's actions");
      ok = false;
    }
  } else {
    ok = false;
  }
  if (!ok) return std::nullopt;
  return rule;
}

void parseActionRules(YamlChecker& c, const YAML::Node& root, TaskSpec& spec) {
  if (!root["action_rules"]) return;
  if (!root["action_rules"].IsSequence()) {
    c.error(root["action_rules"], "action_rules must be a list of {mover, target, load, action}");
    return;
  }
  for (const auto& node : root["action_rules"]) {
    if (!node.IsMap()) {
      c.error(node, "an action rule must be a mapping {mover, target, load, action}");
      continue;
    }
    if (auto rule = parseActionRule(c, node, spec)) spec.action_rules.push_back(*rule);
  }
}

void parseFormatAndName(YamlChecker& c, const YAML::Node& root, TaskSpec& spec) {
  std::string format;
  if (const YAML::Node f = c.required(root, "format", "", std::string("expected '") + kFormat + "'");
      f && c.scalar(f, "format", format) && format != kFormat)
    c.error(f, "format '" + format + "' is not supported (expected '" + kFormat + "')");
  if (root["name"]) c.text(root["name"], "name", spec.name);
}

void parseRadius(YamlChecker& c, const YAML::Node& root, TaskSpec& spec) {
  if (root["arrival_radius"]) {
    double r = 0;
    if (c.number(root["arrival_radius"], "arrival_radius", r)) {
      if (r <= 0) c.error(root["arrival_radius"], "arrival_radius must be positive (metres)");
      else spec.arrival_radius = r;
    }
  }

  // Steps were once grouped within a fixed window; the rule needs none now.
  if (root["step_window_s"])
    c.error(root["step_window_s"],
            "step_window_s is no longer read: a token joins its step while every token of the step still runs, "
            "however late it begins (docs/task-format.md, \"Step grouping\"); delete this line");
}

}  // namespace

TaskSpec parseTaskYaml(const std::string& text, const std::string& file) {
  YamlChecker c(file);
  const YAML::Node root = c.parse(text);
  c.throwIfErrors();
  TaskSpec spec;
  if (!root.IsMap()) {
    throw Error(Diagnostic{file, 1, 1, "task.yaml must be a mapping with format, entities, ..."});
  }
  c.onlyKeys(
      root,
      {"format", "name", "entities", "actions", "arrival_radius", "step_window_s", "goal_conditions", "action_rules"},
      "task.yaml");

  parseFormatAndName(c, root, spec);
  const std::set<std::string> names = parseEntities(c, root, spec);
  parseActions(c, root, spec);
  parseRadius(c, root, spec);
  parseGoalConditions(c, root, names, spec);
  parseActionRules(c, root, spec);
  c.throwIfErrors();
  return spec;
}

TaskSpec readTaskYaml(const std::string& path) {
  return parseTaskYaml(readTextFile(path), path);
}

std::string taskYamlText(const TaskSpec& spec) {
  std::ostringstream out;
  out << "format: " << kFormat << "\n";
  YAML::Emitter name;
  name << spec.name;
  out << "name: " << (spec.name.empty() ? "''" : name.c_str()) << "\n";
  out << "entities:                        # order = node order of the graph\n";
  for (const auto& e : spec.entities) {
    out << "  - {name: " << e.name << ", kind: " << toString(e.kind);
    if (!e.type.empty()) {
      YAML::Emitter type;
      type << e.type;
      out << ", type: " << type.c_str();
    }
    if (e.radius_m) out << ", radius: " << detail::shortestNumber(*e.radius_m);
    if (e.obstacle) out << ", obstacle: " << (*e.obstacle ? "true" : "false");
    out << "}\n";
  }
  if (spec.actions_declared) {
    out << "actions: [";
    for (size_t i = 0; i < spec.actions.size(); ++i) out << (i ? ", " : "") << spec.actions[i];
    out << "]\n";
  }
  out << "arrival_radius: " << detail::shortestNumber(spec.arrival_radius) << "                # metres\n";
  if (!spec.goal_conditions.empty()) {
    out << "goal_conditions:\n";
    for (const auto& g : spec.goal_conditions) {
      out << "  - {entity: " << g.entity << ", at: " << g.at << ", tolerance: " << detail::shortestNumber(g.tolerance)
          << "}\n";
    }
  }
  if (!spec.action_rules.empty()) {
    out << "action_rules:                    # action words of motions for ddace label; the first match wins\n";
    const auto kindAndType = [](EntityKind kind, const std::string& type) {
      YAML::Emitter e;
      e << (std::string(toString(kind)) + (type.empty() ? "" : "/" + type));
      return std::string(e.c_str());
    };
    for (const auto& r : spec.action_rules) {
      out << "  - {";
      if (r.mover_kind) out << "mover: " << kindAndType(*r.mover_kind, r.mover_type) << ", ";
      if (r.target_kind) out << "target: " << kindAndType(*r.target_kind, r.target_type) << ", ";
      if (r.load != ActionRule::Load::Any) out << "load: " << toString(r.load) << ", ";
      out << "action: " << r.action << "}\n";
    }
  }
  return out.str();
}

void writeTaskYaml(const TaskSpec& spec, const std::string& path) {
  writeTextFile(path, taskYamlText(spec));
}

}  // namespace ddace::task
