// task.yaml: every rule of docs/task-format.md, errors with file:line:column.
#include <gtest/gtest.h>

#include "ddace/task/task_spec.h"

using namespace ddace;
using namespace ddace::task;

namespace {

const char* kGood = R"(format: ddace-task/1
name: relay
entities:
  - {name: R1, kind: robot, type: hamster}
  - {name: R2, kind: robot, type: hamster}
  - {name: B1, kind: object}
  - {name: G1, kind: goal}
actions: [move, carry, pass]
arrival_radius: 0.04
goal_conditions:
  - {entity: B1, at: G1, tolerance: 0.05}
)";

/// The single diagnostic of parsing `text`, which must fail.
Diagnostic onlyError(const std::string& text) {
  try {
    parseTaskYaml(text, "task.yaml");
  } catch (const Error& e) {
    EXPECT_EQ(e.diagnostics().size(), 1u) << e.what();
    return e.diagnostics().front();
  }
  ADD_FAILURE() << "expected an error for:\n" << text;
  return {};
}

}  // namespace

TEST(TaskSpec, ParsesTheSpecExample) {
  const TaskSpec s = parseTaskYaml(kGood, "task.yaml");
  EXPECT_EQ(s.name, "relay");
  ASSERT_EQ(s.entities.size(), 4u);
  EXPECT_EQ(s.entities[0].name, "R1");
  EXPECT_EQ(s.entities[0].type, "hamster");
  EXPECT_EQ(s.entities[2].kind, EntityKind::Object);
  EXPECT_EQ(s.entities[3].kind, EntityKind::Goal);
  EXPECT_EQ(s.entityIndex("B1"), 2);
  EXPECT_EQ(s.entityIndex("X"), -1);
  EXPECT_TRUE(s.actions_declared);
  EXPECT_EQ(s.actions, (std::vector<std::string>{"move", "carry", "pass"}));
  EXPECT_DOUBLE_EQ(s.arrival_radius, 0.04);
  ASSERT_EQ(s.goal_conditions.size(), 1u);
  EXPECT_EQ(s.goal_conditions[0].entity, "B1");
  EXPECT_DOUBLE_EQ(s.goal_conditions[0].tolerance, 0.05);
}

TEST(TaskSpec, DefaultsWhenOptionalKeysAreAbsent) {
  const TaskSpec s = parseTaskYaml("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\n", "t");
  EXPECT_FALSE(s.actions_declared);
  EXPECT_TRUE(s.allowsAction("anything"));
  EXPECT_DOUBLE_EQ(s.arrival_radius, kDefaultArrivalRadius);
  EXPECT_TRUE(s.goal_conditions.empty());
}

TEST(TaskSpec, WriteReadRoundTrip) {
  const TaskSpec a = parseTaskYaml(kGood, "task.yaml");
  const TaskSpec b = parseTaskYaml(taskYamlText(a), "again.yaml");
  EXPECT_EQ(taskYamlText(a), taskYamlText(b));
  EXPECT_EQ(b.entityNames(), a.entityNames());
  EXPECT_EQ(b.actions, a.actions);
  EXPECT_DOUBLE_EQ(b.arrival_radius, a.arrival_radius);
  EXPECT_EQ(b.goal_conditions.size(), 1u);
}

TEST(TaskSpec, UnknownTopLevelKeyIsAnErrorAtItsPosition) {
  const Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\nspeed: 3\n");
  EXPECT_EQ(d.file, "task.yaml");
  EXPECT_EQ(d.line, 4);
  EXPECT_EQ(d.column, 1);
  EXPECT_NE(d.message.find("unknown key 'speed'"), std::string::npos);
}

TEST(TaskSpec, UnknownKindIsAnError) {
  const Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: tank}\n");
  EXPECT_EQ(d.line, 3);
  EXPECT_EQ(d.column, 22);
  EXPECT_NE(d.message.find("unknown kind 'tank'"), std::string::npos);
}

TEST(TaskSpec, ControlCharacterInTypeIsAnErrorAtItsPosition) {
  // Found by the task_yaml fuzzer: such a type did not survive taskYamlText -> parseTaskYaml.
  const Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, type: \"ha\\x03m\"}\n");
  EXPECT_EQ(d.line, 3);
  EXPECT_NE(d.message.find("control character"), std::string::npos) << d.message;
}

TEST(TaskSpec, ATaskNameThatIsNotUtf8IsAnErrorAtItsPosition) {
  // Found by the task_yaml fuzzer: the writer wrote such a name back as U+FFFD, another name.
  const Diagnostic d = onlyError("format: ddace-task/1\nname: \"tas\x98k\"\nentities:\n  - {name: R1, kind: robot}\n");
  EXPECT_EQ(d.line, 2);
  EXPECT_EQ(d.column, 7);
  EXPECT_NE(d.message.find("name must be printable UTF-8 text (not UTF-8 at byte 4)"), std::string::npos) << d.message;
}

TEST(TaskSpec, DuplicateNameIsAnError) {
  const Diagnostic d =
      onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\n  - {name: R1, kind: goal}\n");
  EXPECT_EQ(d.line, 4);
  EXPECT_NE(d.message.find("duplicate entity name 'R1'"), std::string::npos);
}

TEST(TaskSpec, InvalidNameIsAnError) {
  const Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: 1R, kind: robot}\n");
  EXPECT_NE(d.message.find("must match"), std::string::npos);
}

TEST(TaskSpec, GoalConditionNamingUnknownEntityIsAnError) {
  const Diagnostic d = onlyError(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\ngoal_conditions:\n"
      "  - {entity: R1, at: G9}\n");
  EXPECT_EQ(d.line, 5);
  EXPECT_NE(d.message.find("unknown entity 'G9'"), std::string::npos);
}

TEST(TaskSpec, UnknownKeyInsideAnEntityIsAnError) {
  const Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, colour: red}\n");
  EXPECT_NE(d.message.find("unknown key 'colour'"), std::string::npos);
}

TEST(TaskSpec, WrongFormatAndMissingEntitiesAreErrors) {
  EXPECT_NE(onlyError("format: ddace-task/2\nentities:\n  - {name: R1, kind: robot}\n").message.find("not supported"),
            std::string::npos);
  EXPECT_NE(onlyError("format: ddace-task/1\n").message.find("missing key 'entities'"), std::string::npos);
  // A key without a value is missing, and the format's says what it must be.
  EXPECT_NE(onlyError("format: ddace-task/1\nentities:\n").message.find("missing key 'entities'"), std::string::npos);
  EXPECT_EQ(onlyError("format:\nentities: [{name: R1, kind: robot}]\n").message,
            "missing key 'format' (expected 'ddace-task/1')");
}

TEST(TaskSpec, BadArrivalRadiusIsAnError) {
  EXPECT_NE(onlyError("format: ddace-task/1\nentities: [{name: R1, kind: robot}]\narrival_radius: -1\n")
                .message.find("positive"),
            std::string::npos);
  EXPECT_NE(onlyError("format: ddace-task/1\nentities: [{name: R1, kind: robot}]\narrival_radius: abc\n")
                .message.find("not a finite number"),
            std::string::npos);
}

TEST(TaskSpec, YamlSyntaxErrorNamesLineAndColumn) {
  const Diagnostic d = onlyError("format: ddace-task/1\nentities: [\n");
  EXPECT_EQ(d.file, "task.yaml");
  EXPECT_GT(d.line, 0);
  EXPECT_NE(d.message.find("YAML syntax error"), std::string::npos);
}

TEST(TaskSpec, EveryErrorIsReportedNotJustTheFirst) {
  try {
    parseTaskYaml("format: ddace-task/1\nentities:\n  - {name: R1, kind: tank}\n  - {name: R1, kind: robot}\nfoo: 1\n",
                  "task.yaml");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.diagnostics().size(), 3u) << e.what();
  }
}

TEST(TaskSpec, MissingFileNamesTheFile) {
  try {
    readTaskYaml("/nonexistent/task.yaml");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/task.yaml"), std::string::npos);
  }
}

TEST(TaskSpec, AStepWindowIsRefusedNamingTheRuleThatReplacedIt) {
  // Steps were grouped within step_window_s; they are grouped by the tokens that still run
  // now, so a task.yaml that sets a window is told so rather than silently regrouped.
  const std::string head = "format: ddace-task/1\nentities: [{name: R1, kind: robot}]\n";
  for (const std::string value : {"0.7", "0", "abc"}) {
    const Diagnostic d = onlyError(head + "step_window_s: " + value + "\n");
    EXPECT_EQ(d.file, "task.yaml");
    EXPECT_EQ(d.line, 3) << value;
    EXPECT_NE(d.message.find("step_window_s is no longer read"), std::string::npos) << d.message;
    EXPECT_NE(d.message.find("every token of the step still runs"), std::string::npos) << d.message;
  }
  EXPECT_EQ(taskYamlText(parseTaskYaml(head, "t")).find("step_window"), std::string::npos);
}

TEST(TaskSpec, FootprintDefaultsByKind) {
  // A task.yaml without footprints (every task file before them) reads with the defaults.
  const TaskSpec s = parseTaskYaml(kGood, "task.yaml");
  const Footprint robot = s.footprint(0), object = s.footprint(2), goal = s.footprint(3);
  EXPECT_DOUBLE_EQ(robot.radius_m, kDefaultRobotRadius);
  EXPECT_TRUE(robot.obstacle);
  EXPECT_DOUBLE_EQ(object.radius_m, kDefaultObjectRadius);
  EXPECT_TRUE(object.obstacle);
  EXPECT_DOUBLE_EQ(goal.radius_m, kDefaultGoalRadius);
  EXPECT_FALSE(goal.obstacle);  // a flat print: robots drive onto it
  // Two Hamsters touch 3-4.5 cm apart (a 3.2 x 3.0 cm body); the disc is the outer bound.
  EXPECT_GE(s.contactDistance(0, 1), 0.03);
  EXPECT_LE(s.contactDistance(0, 1), 0.045);
  EXPECT_DOUBLE_EQ(s.contactDistance(0, 2), kDefaultRobotRadius + kDefaultObjectRadius);
  // Nothing stated, nothing written: the file stays as it was.
  EXPECT_EQ(taskYamlText(s).find(", radius:"), std::string::npos);
}

TEST(TaskSpec, StatedFootprintsOverrideTheDefaultsAndRoundTrip) {
  const TaskSpec s = parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, type: uav, radius: 0.05}\n"
      "  - {name: B1, kind: object, obstacle: false}\n  - {name: G1, kind: goal, radius: 0.1, obstacle: true}\n",
      "task.yaml");
  EXPECT_DOUBLE_EQ(s.footprint(0).radius_m, 0.05);
  EXPECT_TRUE(s.footprint(0).obstacle);
  EXPECT_DOUBLE_EQ(s.footprint(1).radius_m, kDefaultObjectRadius);
  EXPECT_FALSE(s.footprint(1).obstacle);
  EXPECT_DOUBLE_EQ(s.footprint(2).radius_m, 0.1);
  EXPECT_TRUE(s.footprint(2).obstacle);
  EXPECT_DOUBLE_EQ(s.contactDistance(0, 2), 0.15);
  EXPECT_DOUBLE_EQ(s.contactDistance(0, 1), 0.0) << "a flat object is driven onto, never touched";
  const TaskSpec again = parseTaskYaml(taskYamlText(s), "again.yaml");
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(again.entities[i].radius_m, s.entities[i].radius_m) << i;
    EXPECT_EQ(again.entities[i].obstacle, s.entities[i].obstacle) << i;
  }
  EXPECT_EQ(taskYamlText(again), taskYamlText(s));
}

TEST(TaskSpec, BadFootprintIsAnErrorAtItsPosition) {
  Diagnostic d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, radius: 0}\n");
  EXPECT_EQ(d.line, 3);
  EXPECT_EQ(d.column, 37);
  EXPECT_NE(d.message.find("radius must be > 0"), std::string::npos) << d.message;
  d = onlyError("format: ddace-task/1\nentities:\n  - {name: R1, kind: robot, radius: nan}\n");
  EXPECT_NE(d.message.find("not a finite number"), std::string::npos) << d.message;
  d = onlyError("format: ddace-task/1\nentities:\n  - {name: G1, kind: goal, obstacle: maybe}\n");
  EXPECT_EQ(d.line, 3);
  EXPECT_NE(d.message.find("obstacle: 'maybe' is not true or false"), std::string::npos) << d.message;
}

TEST(TaskSpec, ActionRulesParseMatchAndRoundTrip) {
  const TaskSpec s = parseTaskYaml(std::string(kGood) + R"(action_rules:
  - {mover: robot, load: carries, action: carry}
  - {mover: object, target: robot/hamster, action: pass}
  - {mover: robot/hamster, target: goal, load: none, action: move}
  - {action: move}
)",
                                   "task.yaml");
  ASSERT_EQ(s.action_rules.size(), 4u);
  const ActionRule& carry = s.action_rules[0];
  EXPECT_EQ(carry.mover_kind, EntityKind::Robot);
  EXPECT_FALSE(carry.target_kind.has_value());
  EXPECT_EQ(carry.load, ActionRule::Load::Carries);
  // entities: R1, R2 (robots, hamster), B1 (object), G1 (goal); load as label::kindKey: 0, 1, 2.
  EXPECT_TRUE(carry.matches(s.entities[0], s.entities[3], 1));
  EXPECT_FALSE(carry.matches(s.entities[0], s.entities[3], 0));
  const ActionRule& pass = s.action_rules[1];
  EXPECT_TRUE(pass.matches(s.entities[2], s.entities[1], 0));
  EXPECT_FALSE(pass.matches(s.entities[2], s.entities[3], 0));               // a goal, not a hamster
  EXPECT_FALSE(s.action_rules[2].matches(s.entities[0], s.entities[3], 1));  // load: none
  EXPECT_TRUE(s.action_rules[3].matches(s.entities[2], s.entities[3], 2));   // no field: every motion
  const TaskSpec again = parseTaskYaml(taskYamlText(s), "again.yaml");
  ASSERT_EQ(again.action_rules.size(), 4u);
  EXPECT_EQ(again.action_rules[2].mover_type, "hamster");
  EXPECT_EQ(again.action_rules[2].load, ActionRule::Load::None);
  EXPECT_EQ(taskYamlText(again), taskYamlText(s));
}

TEST(TaskSpec, BadActionRuleIsAnErrorAtItsPosition) {
  const std::string head = std::string(kGood) + "action_rules:\n";  // the rule is on line 13
  Diagnostic d = onlyError(head + "  - {mover: robot, action: fly}\n");
  EXPECT_EQ(d.line, 13);
  EXPECT_NE(d.message.find("action 'fly' is not in the task's actions"), std::string::npos) << d.message;
  d = onlyError(head + "  - {mover: goal, action: move}\n");
  EXPECT_EQ(d.line, 13);
  EXPECT_NE(d.message.find("a goal does not act"), std::string::npos) << d.message;
  d = onlyError(head + "  - {mover: robot, load: maybe, action: move}\n");
  EXPECT_NE(d.message.find("load 'maybe' must be none, carries or carried"), std::string::npos) << d.message;
  d = onlyError(head + "  - {target: table, action: move}\n");
  EXPECT_NE(d.message.find("target 'table' must be robot, object or goal"), std::string::npos) << d.message;
  d = onlyError(head + "  - {mover: robot}\n");
  EXPECT_NE(d.message.find("action rule without 'action'"), std::string::npos) << d.message;
  d = onlyError(head + "  - {mover: robot, speed: 2, action: move}\n");
  EXPECT_NE(d.message.find("speed"), std::string::npos) << d.message;
}
