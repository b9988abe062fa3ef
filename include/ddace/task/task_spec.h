// The scene of a task: task.yaml of format ddace-task/1 (docs/task-format.md).
//
// Owns: parsing, validating and writing task.yaml. Entity order is the node
// order of every graph built from the task. Units: metres (REP-103), table frame.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "ddace/common/error.h"

namespace ddace::task {

inline constexpr const char* kFormat = "ddace-task/1";
inline constexpr double kDefaultArrivalRadius = 0.03;  // metres

enum class EntityKind { Robot, Object, Goal };

/// "robot", "object", "goal".
const char* toString(EntityKind kind);
/// Parses "robot"/"object"/"goal"; nullopt otherwise.
std::optional<EntityKind> entityKindFromString(const std::string& s);

/// Footprint defaults (docs/task-format.md, "Bodies"), metres. A Hamster's body is about
/// 3.2 cm x 3.0 cm (3.5 cm tall): the disc around it has a radius of 2.2 cm, so two
/// Hamsters touch at most 4.4 cm apart, centre to centre. Robots of any other type get the
/// same disc (the testbed's robots are Hamsters; state another robot's radius).
inline constexpr double kDefaultRobotRadius = 0.022;
/// An object (a box, a ball, cargo) with the default 3 cm marker on top: a 4 cm body.
inline constexpr double kDefaultObjectRadius = 0.02;
/// A goal: a flat print of the default 4 cm goal marker; robots drive onto it.
inline constexpr double kDefaultGoalRadius = 0.02;

/// An entity's body on the table: a disc around its tracked centre.
struct Footprint {
  double radius_m = kDefaultRobotRadius;  ///< metres, > 0
  /// True for a body that others must not overlap (robots, objects); false for a flat
  /// print that robots drive onto (goals).
  bool obstacle = true;
};

struct Entity {
  std::string name;  ///< [A-Za-z][A-Za-z0-9_]*, unique within the task
  EntityKind kind = EntityKind::Robot;
  std::string type;  ///< free text ("hamster", "uav"), may be empty
  /// As stated in task.yaml (`radius`, `obstacle`); unset = the default of the kind.
  /// Read them through footprint(), which resolves the defaults. (Initialised, so that
  /// {name, kind, type} still initialises an entity without a warning.)
  std::optional<double> radius_m = std::nullopt;
  std::optional<bool> obstacle = std::nullopt;
};

/// The footprint of `e`: its stated radius and obstacle flag, else the defaults of its
/// kind (robot: kDefaultRobotRadius, obstacle; object: kDefaultObjectRadius, obstacle;
/// goal: kDefaultGoalRadius, not an obstacle). The one accessor every part uses.
Footprint footprint(const Entity& e);

/// The action word of a kind of motion, for labels inferred from motion (`ddace label`,
/// docs/labels.md; task.yaml `action_rules`). Every stated field must match; the first
/// matching rule of the list names the word.
struct ActionRule {
  enum class Load { Any, None, Carries, Carried };
  std::optional<EntityKind> mover_kind;   ///< unset: any mover
  std::string mover_type;                 ///< empty: any type
  std::optional<EntityKind> target_kind;  ///< unset: any target
  std::string target_type;                ///< empty: any type
  Load load = Load::Any;                  ///< None: moved without a load; Carries: with one; Carried: was one
  std::string action;                     ///< the word (in `actions` when the task declares them)

  /// True for a motion of `mover` ending at `target`; `load` as label::kindKey takes it
  /// (0 none, 1 it carried a load, 2 it was one).
  bool matches(const Entity& mover, const Entity& target, int load) const;
};

/// "none", "carries", "carried" ("" for Any).
const char* toString(ActionRule::Load load);

/// At the end of an execution, `entity` must be within `tolerance` metres of `at`.
struct GoalCondition {
  std::string entity;
  std::string at;
  double tolerance = 0.05;  ///< metres
};

struct TaskSpec {
  std::string name;
  std::vector<Entity> entities;                   ///< order = node order
  std::vector<std::string> actions;               ///< declared vocabulary (empty when absent)
  bool actions_declared = false;                  ///< true when task.yaml lists `actions`
  double arrival_radius = kDefaultArrivalRadius;  ///< metres
  std::vector<GoalCondition> goal_conditions;
  std::vector<ActionRule> action_rules;  ///< in task.yaml's order (the first match wins)

  /// Index of the entity called `name`, or -1.
  int entityIndex(const std::string& name) const;
  /// True when `action` is in the declared vocabulary (always true when none is declared).
  bool allowsAction(const std::string& action) const;
  /// Names of all entities, in order.
  std::vector<std::string> entityNames() const;
  /// footprint(entities[i]).
  Footprint footprint(int i) const;
  /// The centre distance at which the bodies of entities a and b touch: the sum of
  /// their radii, 0 when either is no obstacle (a flat goal is driven onto, never
  /// touched); metres. The contact of task/body_geometry.h.
  double contactDistance(int a, int b) const;
};

/// True for names matching [A-Za-z][A-Za-z0-9_]*.
bool isValidName(const std::string& name);

/// Parses task.yaml text. `file` is used in diagnostics only.
/// Throws ddace::Error listing every problem with file:line:column.
TaskSpec parseTaskYaml(const std::string& text, const std::string& file);
/// Reads and parses a task.yaml file: a regular file of at most kMaxInputFileBytes
/// (common/file.h, 64 MiB; a FIFO, a device, a directory or a symlink loop is refused by
/// name before it is opened). Throws ddace::Error.
TaskSpec readTaskYaml(const std::string& path);
/// Serialises to task.yaml text (round-trips through parseTaskYaml: numbers are written
/// with the shortest digits that read back exactly).
std::string taskYamlText(const TaskSpec& spec);
/// Writes task.yaml, checked and atomically. Throws ddace::Error naming the file when it
/// cannot be written; no half-written file is left under its name.
void writeTaskYaml(const TaskSpec& spec, const std::string& path);

}  // namespace ddace::task
