// Demonstration CSVs: keyframes, steps and tokens, segments, snapshots, every listed error.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "ddace/common/random.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/summary.h"
#include "ddace/task/task_dir.h"

#include "../common/file_tree.h"

using namespace ddace;
using namespace ddace::task;
using ddace::test::writeBytes;

namespace {

TaskSpec scene(bool declare_actions = true) {
  return parseTaskYaml(std::string("format: ddace-task/1\nentities:\n"
                                   "  - {name: R1, kind: robot}\n  - {name: R2, kind: robot}\n"
                                   "  - {name: B1, kind: object}\n  - {name: G1, kind: goal}\n") +
                           (declare_actions ? "actions: [move, carry, stop]\n" : ""),
                       "task.yaml");
}

const char* kHeader = "t,R1.x,R1.y,R1.action,R1.target,R2.x,R2.y,R2.action,R2.target,B1.x,B1.y,G1.x,G1.y\n";

std::string row(double t, const std::string& a1, const std::string& t1, const std::string& a2, const std::string& t2,
                double x1 = 0.1) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%g,%g,0.1,%s,%s,0.5,0.5,%s,%s,0.2,0.2,0.9,0.9\n", t, x1, a1.c_str(), t1.c_str(),
                a2.c_str(), t2.c_str());
  return buf;
}

Diagnostic firstError(const std::string& text, const TaskSpec& spec = scene()) {
  try {
    parseDemonstrationCsv(text, spec, "demo.csv");
  } catch (const Error& e) {
    return e.diagnostics().front();
  }
  ADD_FAILURE() << "expected an error for:\n" << text;
  return {};
}

}  // namespace

TEST(Demonstration, KeyframesStepsSegmentsAndSnapshots) {
  // rows: 0 idle | 1-3 R1 move->G1 (+ R2 carry->B1 rows 1-2) | 4 idle | 5-6 R2 stop | 7 idle
  std::string csv = kHeader;
  csv += row(0.0, "", "", "", "");
  csv += row(0.1, "move", "G1", "carry", "B1", 0.2);
  csv += row(0.2, "move", "G1", "carry", "B1", 0.3);
  csv += row(0.3, "move", "G1", "idle", "", 0.4);
  csv += row(0.4, "idle", "", "", "", 0.5);
  csv += row(0.5, "", "", "stop", "", 0.5);
  csv += row(0.6, "", "", "stop", "", 0.5);
  csv += row(0.7, "", "", "", "", 0.5);
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  ASSERT_EQ(d.rows(), 8u);
  // Row 3 changes (R2 goes idle), but a row in which labels only end opens no step.
  EXPECT_EQ(d.keyframes, (std::vector<int>{1, 5}));
  ASSERT_EQ(d.steps.size(), 2u);
  ASSERT_EQ(d.steps[0].tokens.size(), 2u);
  EXPECT_EQ(tokenKey(d.steps[0].tokens[0], spec), "R1:move:G1");
  EXPECT_EQ(tokenKey(d.steps[0].tokens[1], spec), "R2:carry:B1");
  ASSERT_EQ(d.steps[1].tokens.size(), 1u);
  EXPECT_EQ(tokenKey(d.steps[1].tokens[0], spec), "R2:stop");
  EXPECT_FALSE(d.steps[1].tokens[0].isMotion());

  ASSERT_EQ(d.segments.size(), 3u);
  EXPECT_EQ(d.segments[0].first_row, 1);
  EXPECT_EQ(d.segments[0].last_row, 3);  // up to the last row before R1's label changes
  EXPECT_EQ(d.segments[1].last_row, 2);
  EXPECT_EQ(d.segments[2].first_row, 5);
  EXPECT_EQ(d.segments[2].last_row, 6);
  const auto path = d.segmentPath(d.segments[0]);
  ASSERT_EQ(path.size(), 3u);
  EXPECT_DOUBLE_EQ(path.front().x(), 0.2);
  EXPECT_DOUBLE_EQ(path.back().x(), 0.4);
  EXPECT_DOUBLE_EQ(d.segmentGoal(d.segments[0]).x(), 0.9);  // G1 at the keyframe

  // One snapshot per step plus the terminal END snapshot from the last row.
  ASSERT_EQ(d.snapshots.size(), 3u);
  EXPECT_EQ(d.snapshots[0].row, 1);
  EXPECT_FALSE(d.snapshots[0].end);
  EXPECT_DOUBLE_EQ(d.snapshots[0].positions[0].x(), 0.2);
  EXPECT_TRUE(d.snapshots.back().end);
  EXPECT_EQ(d.snapshots.back().row, 7);
}

TEST(Demonstration, RowZeroIsAKeyframeWhenNotAllNull) {
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "", "");
  csv += row(0.1, "move", "G1", "", "");
  const Demonstration d = parseDemonstrationCsv(csv, scene(), "demo.csv");
  EXPECT_EQ(d.keyframes, (std::vector<int>{0}));
  ASSERT_EQ(d.steps.size(), 1u);
  EXPECT_EQ(d.segments[0].first_row, 0);
  EXPECT_EQ(d.segments[0].last_row, 1);
}

TEST(Demonstration, AllNullRowZeroIsNotAKeyframe) {
  std::string csv = kHeader;
  csv += row(0.0, "idle", "", "", "");
  csv += row(0.1, "move", "G1", "", "");
  const Demonstration d = parseDemonstrationCsv(csv, scene(), "demo.csv");
  EXPECT_EQ(d.keyframes, (std::vector<int>{1}));
}

TEST(Demonstration, SwitchingTargetWithoutIdlingIsANewToken) {
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "move", "G1");
  csv += row(0.1, "move", "B1", "move", "G1");  // R1 switches target, R2 continues
  csv += row(0.2, "move", "B1", "move", "G1");
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  EXPECT_EQ(d.keyframes, (std::vector<int>{0, 1}));
  ASSERT_EQ(d.steps[1].tokens.size(), 1u);  // only the entity whose own label changed
  EXPECT_EQ(tokenKey(d.steps[1].tokens[0], spec), "R1:move:B1");
  EXPECT_EQ(d.segments[0].last_row, 0);  // R1's first segment ended when its label changed
  EXPECT_EQ(d.segments[1].last_row, 2);  // R2's continues to the end
}

// ---- step grouping (docs/task-format.md, "Step grouping")

namespace {

std::vector<std::vector<std::string>> structure(const Demonstration& d, const TaskSpec& spec) {
  std::vector<std::vector<std::string>> out;
  for (const auto& s : d.steps) {
    out.emplace_back();
    for (const auto& t : s.tokens) out.back().push_back(tokenKey(t, spec));
  }
  return out;
}

using Steps = std::vector<std::vector<std::string>>;

}  // namespace

TEST(StepGrouping, ALateTokenJoinsTheStepAndItsGoalIsTakenAtTheKeyframe) {
  // R1 starts at row 1; R2's label (toward the moving R1) begins 0.2 s later, at row 3.
  std::string csv = kHeader;
  csv += row(0.0, "", "", "", "", 0.1);
  csv += row(0.1, "move", "G1", "", "", 0.2);
  csv += row(0.2, "move", "G1", "", "", 0.3);
  csv += row(0.3, "move", "G1", "move", "R1", 0.4);
  csv += row(0.4, "move", "G1", "move", "R1", 0.5);
  csv += row(0.5, "", "", "", "", 0.6);
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  EXPECT_EQ(structure(d, spec), (Steps{{"R1:move:G1", "R2:move:R1"}}));
  EXPECT_EQ(d.keyframes, (std::vector<int>{1}));
  ASSERT_EQ(d.snapshots.size(), 2u);
  EXPECT_EQ(d.snapshots[0].row, 1);  // the step's snapshot is its first token's row
  EXPECT_DOUBLE_EQ(d.snapshots[0].positions[0].x(), 0.2);
  ASSERT_EQ(d.segments.size(), 2u);
  EXPECT_EQ(d.segments[1].first_row, 3);  // the late token's segment starts at its own row
  EXPECT_EQ(d.segments[1].step, 0);
  EXPECT_EQ(d.segmentPath(d.segments[1]).size(), 2u);
  EXPECT_DOUBLE_EQ(d.segmentGoal(d.segments[1]).x(), 0.2);  // R1 where the step was decided
  ASSERT_EQ(d.steps[0].late.size(), 1u);
  EXPECT_EQ(tokenKey(d.steps[0].late[0].token, spec), "R2:move:R1");
  EXPECT_EQ(d.steps[0].late[0].row, 3);
  EXPECT_NEAR(d.steps[0].late[0].delay_s, 0.2, 1e-12);
  EXPECT_TRUE(d.snapshots.back().end);
  EXPECT_EQ(d.snapshots.back().row, 5);
}

TEST(StepGrouping, ALateTokenAfterAnotherTokenOfTheStepEndedOpensANewStep) {
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "", "");
  csv += row(0.1, "move", "G1", "", "");
  csv += row(0.2, "", "", "move", "G1");  // R1 ended in this very row: a new step
  csv += row(0.3, "", "", "move", "G1");
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  EXPECT_EQ(structure(d, spec), (Steps{{"R1:move:G1"}, {"R2:move:G1"}}));
  EXPECT_EQ(d.keyframes, (std::vector<int>{0, 2}));
  EXPECT_TRUE(d.steps[1].late.empty());
}

TEST(StepGrouping, AnInPlaceTokenOfOneRowEndsItsStepAtTheNextRow) {
  std::string csv = kHeader;
  csv += row(0.0, "stop", "", "move", "G1");  // same row: one step, nothing late
  csv += row(0.1, "", "", "move", "G1");
  csv += row(0.2, "", "", "", "");
  csv += row(0.3, "stop", "", "", "");
  csv += row(0.4, "", "", "move", "G1");  // R1's one-row stop has ended: a new step
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  EXPECT_EQ(structure(d, spec), (Steps{{"R1:stop", "R2:move:G1"}, {"R1:stop"}, {"R2:move:G1"}}));
  EXPECT_TRUE(d.steps[0].late.empty());
  EXPECT_EQ(d.segments[2].first_row, d.segments[2].last_row);  // a single row
}

TEST(StepGrouping, AnEntityWhoseLabelChangesTwiceWithinTheWindowOpensANewStep) {
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "", "");
  csv += row(0.1, "move", "B1", "", "");        // R1 corrects itself: its first token ended
  csv += row(0.2, "move", "B1", "move", "G1");  // R2 joins R1's second token
  csv += row(0.3, "move", "B1", "move", "G1");
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
  EXPECT_EQ(structure(d, spec), (Steps{{"R1:move:G1"}, {"R1:move:B1", "R2:move:G1"}}));
  ASSERT_EQ(d.steps[1].late.size(), 1u);
  EXPECT_EQ(d.steps[1].late[0].row, 2);
}

// People start the robots of one step one after the other, some a second or more apart:
// a token joins its step while every token of the step still runs, however late. Two
// pairs shown by hand with the second robot up to 1 s behind: 27 of 20 demonstrations'
// 40 steps split under a 0.5 s window (OSR 0.13), none under this rule.
TEST(StepGrouping, ALateTokenJoinsWhileEveryTokenOfTheStepRunsHoweverLate) {
  for (const double late_t : {0.5, 1.2, 3.0}) {
    std::string csv = kHeader;
    csv += row(0.0, "move", "G1", "", "");
    csv += row(late_t, "move", "G1", "move", "G1");
    csv += row(late_t + 1, "move", "G1", "move", "G1");
    csv += row(late_t + 2, "", "", "", "");
    const TaskSpec spec = scene();
    const Demonstration d = parseDemonstrationCsv(csv, spec, "demo.csv");
    EXPECT_EQ(structure(d, spec), (Steps{{"R1:move:G1", "R2:move:G1"}})) << late_t;
    ASSERT_EQ(d.steps[0].late.size(), 1u);
    EXPECT_DOUBLE_EQ(d.steps[0].late[0].delay_s, late_t);
  }
}

TEST(StepGrouping, LabelsThatOnlyEndOpenNoStep) {
  // R2 is released two rows before R1: with grouping no empty step appears there.
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "move", "G1");
  csv += row(0.1, "move", "G1", "", "");
  csv += row(0.2, "move", "G1", "", "");
  csv += row(0.3, "", "", "", "");
  const TaskSpec spec = scene();
  EXPECT_EQ(structure(parseDemonstrationCsv(csv, spec, "demo.csv"), spec), (Steps{{"R1:move:G1", "R2:move:G1"}}));
}

TEST(StepGrouping, SeveralLateTokensJoinWhileNoneHasEnded) {
  // Three tokens labelled 0.6 s apart each join; a fourth after R1's ended opens a step.
  std::string csv =
      "t,R1.x,R1.y,R1.action,R1.target,R2.x,R2.y,R2.action,R2.target,B1.x,B1.y,B1.action,B1.target,G1.x,G1.y\n";
  csv += "0.0,0.1,0.1,move,G1,0.5,0.5,,,0.2,0.2,,,0.9,0.9\n";
  csv += "0.6,0.1,0.1,move,G1,0.5,0.5,move,G1,0.2,0.2,,,0.9,0.9\n";
  csv += "1.2,0.1,0.1,move,G1,0.5,0.5,move,G1,0.2,0.2,carry,G1,0.9,0.9\n";
  csv += "1.8,0.1,0.1,,,0.5,0.5,move,G1,0.2,0.2,carry,G1,0.9,0.9\n";
  csv += "2.4,0.1,0.1,move,B1,0.5,0.5,move,G1,0.2,0.2,carry,G1,0.9,0.9\n";
  const TaskSpec spec = scene();
  EXPECT_EQ(structure(parseDemonstrationCsv(csv, spec, "demo.csv"), spec),
            (Steps{{"R1:move:G1", "R2:move:G1", "B1:carry:G1"}, {"R1:move:B1"}}));
}

TEST(StepGrouping, ValidateNotesSayWhereOnsetsWereMerged) {
  std::string csv = kHeader;
  csv += row(0.0, "move", "G1", "", "");
  csv += row(0.25, "move", "G1", "move", "G1");
  csv += row(0.5, "move", "G1", "move", "G1");
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demos/demo_007.csv");
  const std::vector<Diagnostic> notes = stepGroupingNotes(d, spec);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0].str(),
            "demos/demo_007.csv:3: step 1: R2:move:G1 began 0.250 s after the step's first token "
            "(line 2); merged into the step");
}

// A token that begins after a token of the step ended, while another still runs, makes a
// step of its own, and validate says so with the line its label must begin by to join:
// a person may have started it after a shorter token of the step ended.
TEST(StepGrouping, ValidateNotesSayWhereAStepBeganWhileTheStepBeforeRan) {
  const std::string header =
      "t,R1.x,R1.y,R1.action,R1.target,R2.x,R2.y,R2.action,R2.target,B1.x,B1.y,B1.action,B1.target,G1.x,G1.y\n";
  std::string csv = header;
  csv += "0.0,0.1,0.1,move,G1,0.5,0.5,move,B1,0.2,0.2,,,0.9,0.9\n";
  csv += "0.5,0.1,0.1,move,G1,0.5,0.5,move,B1,0.2,0.2,,,0.9,0.9\n";
  csv += "1.0,0.1,0.1,,,0.5,0.5,move,B1,0.2,0.2,,,0.9,0.9\n";
  csv += "1.5,0.1,0.1,,,0.5,0.5,move,B1,0.2,0.2,carry,G1,0.9,0.9\n";
  csv += "2.0,0.1,0.1,,,0.5,0.5,,,0.2,0.2,carry,G1,0.9,0.9\n";
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "demos/demo_010.csv");
  ASSERT_EQ(structure(d, spec), (Steps{{"R1:move:G1", "R2:move:B1"}, {"B1:carry:G1"}}));
  ASSERT_TRUE(d.steps[1].overlap);
  EXPECT_EQ(d.steps[1].overlap->ended_row, 1);
  const std::vector<Diagnostic> notes = stepGroupingNotes(d, spec);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0].str(),
            "demos/demo_010.csv:5: step 2: B1:carry:G1 began while R2:move:B1 of step 1 still ran, after R1:move:G1 "
            "of it had ended (line 3): a step of its own (a token joins a step while every token of the step runs; "
            "begin its label by line 3 if it belongs to step 1)");
  // After every token of the first step ended, the next one is a step of its own: no note.
  std::string after = kHeader;
  after += row(0.0, "move", "G1", "", "");
  after += row(0.75, "", "", "move", "G1");
  EXPECT_TRUE(stepGroupingNotes(parseDemonstrationCsv(after, spec, "d.csv"), spec).empty());
}

TEST(Demonstration, ColumnsInAnyOrderAndEntitiesWithoutLabelColumns) {
  const std::string csv =
      "G1.y,G1.x,B1.y,B1.x,R2.y,R2.x,R1.target,R1.action,R1.y,R1.x,t\n"
      "0.9,0.9,0.2,0.2,0.5,0.5,G1,move,0.1,0.1,0\n"
      "0.9,0.9,0.2,0.2,0.5,0.5,,,0.1,0.2,1\n";
  const Demonstration d = parseDemonstrationCsv(csv, scene(), "demo.csv");
  EXPECT_TRUE(d.has_label_columns[0]);
  EXPECT_FALSE(d.has_label_columns[1]);
  EXPECT_DOUBLE_EQ(d.positions[1][0].x(), 0.2);
  EXPECT_EQ(d.steps.size(), 1u);
}

TEST(Demonstration, ActionsAreFreeWhenTaskYamlListsNone) {
  std::string csv = kHeader;
  csv += row(0.0, "juggle", "G1", "", "");
  EXPECT_NO_THROW(parseDemonstrationCsv(csv, scene(false), "demo.csv"));
  EXPECT_NE(firstError(csv).message.find("not in task.yaml's actions"), std::string::npos);
}

TEST(Demonstration, WriteReadRoundTripIsExact) {
  std::string csv = kHeader;
  csv += row(0.0, "", "", "", "");
  csv += row(0.05, "move", "G1", "carry", "B1", 0.123456);
  csv += row(0.1, "", "", "stop", "", 0.25);
  const TaskSpec spec = scene();
  const Demonstration a = parseDemonstrationCsv(csv, spec, "a.csv");
  const std::string text = demonstrationCsvText(a, spec);
  const Demonstration b = parseDemonstrationCsv(text, spec, "b.csv");
  EXPECT_EQ(demonstrationCsvText(b, spec), text);
  EXPECT_EQ(b.labels, a.labels);
  EXPECT_EQ(b.keyframes, a.keyframes);
  EXPECT_DOUBLE_EQ(b.positions[1][0].x(), 0.123456);
}

TEST(Demonstration, TokenKeysRoundTripAndBadKeysAreRefused) {
  const TaskSpec spec = scene();
  for (const std::string key : {"R1:move:G1", "R2:stop"}) EXPECT_EQ(tokenKey(parseTokenKey(key, spec), spec), key);
  EXPECT_THROW(parseTokenKey("R9:move:G1", spec), Error);
  EXPECT_THROW(parseTokenKey("R1:fly:G1", spec), Error);
  EXPECT_THROW(parseTokenKey("R1:move:R1", spec), Error);
  EXPECT_THROW(parseTokenKey("R1", spec), Error);
}

// ---- every error of the spec names file, line and column

TEST(DemonstrationErrors, UnknownColumn) {
  const Diagnostic d = firstError(std::string("t,R1.x,R1.y,R1.z,R2.x,R2.y,B1.x,B1.y,G1.x,G1.y\n"));
  EXPECT_EQ(d.file, "demo.csv");
  EXPECT_EQ(d.line, 1);
  EXPECT_EQ(d.column, 13);
  EXPECT_NE(d.message.find("unknown column 'R1.z'"), std::string::npos);
}

TEST(DemonstrationErrors, DuplicatedColumn) {
  const Diagnostic d = firstError("t,R1.x,R1.y,R1.x,R2.x,R2.y,B1.x,B1.y,G1.x,G1.y\n");
  EXPECT_EQ(d.line, 1);
  EXPECT_EQ(d.column, 13);
  EXPECT_NE(d.message.find("duplicated column 'R1.x'"), std::string::npos);
}

TEST(DemonstrationErrors, MissingRequiredColumn) {
  const Diagnostic d = firstError("t,R1.x,R1.y,R2.x,R2.y,B1.x,B1.y,G1.x\n0,0,0,0,0,0,0,0\n");
  EXPECT_EQ(d.line, 1);
  EXPECT_NE(d.message.find("missing required column 'G1.y'"), std::string::npos);
}

TEST(DemonstrationErrors, TargetWithoutActionColumn) {
  const Diagnostic d = firstError("t,R1.x,R1.y,R1.target,R2.x,R2.y,B1.x,B1.y,G1.x,G1.y\n");
  EXPECT_EQ(d.column, 13);
  EXPECT_NE(d.message.find("'R1.target' without 'R1.action'"), std::string::npos);
}

TEST(DemonstrationErrors, TooFewAndTooManyFields) {
  std::string csv = std::string(kHeader) + row(0, "", "", "", "") + "0.1,0.1,0.1\n";
  Diagnostic d = firstError(csv);
  EXPECT_EQ(d.line, 3);
  EXPECT_NE(d.message.find("too few"), std::string::npos);
  csv = std::string(kHeader) + "0,0.1,0.1,,,0.5,0.5,,,0.2,0.2,0.9,0.9,7\n";
  d = firstError(csv);
  EXPECT_EQ(d.line, 2);
  EXPECT_EQ(d.column, 39);  // the first extra field
  EXPECT_NE(d.message.find("too many"), std::string::npos);
}

TEST(DemonstrationErrors, NonFiniteNumber) {
  for (const std::string bad : {"nan", "inf", "abc", ""}) {
    const std::string csv = std::string(kHeader) + "0," + bad + ",0.1,,,0.5,0.5,,,0.2,0.2,0.9,0.9\n";
    const Diagnostic d = firstError(csv);
    EXPECT_EQ(d.line, 2) << bad;
    EXPECT_EQ(d.column, 3) << bad;
    EXPECT_NE(d.message.find("R1.x"), std::string::npos);
    EXPECT_NE(d.message.find("not a finite number"), std::string::npos);
  }
}

TEST(DemonstrationErrors, ActionNotInVocabulary) {
  const Diagnostic d = firstError(std::string(kHeader) + row(0, "fly", "G1", "", ""));
  EXPECT_EQ(d.line, 2);
  EXPECT_EQ(d.column, 11);
  EXPECT_NE(d.message.find("action 'fly'"), std::string::npos);
}

TEST(DemonstrationErrors, UnknownTarget) {
  const Diagnostic d = firstError(std::string(kHeader) + row(0, "move", "X9", "", ""));
  EXPECT_EQ(d.column, 16);
  EXPECT_NE(d.message.find("unknown target 'X9'"), std::string::npos);
}

TEST(DemonstrationErrors, TargetEqualToItself) {
  const Diagnostic d = firstError(std::string(kHeader) + row(0, "move", "R1", "", ""));
  EXPECT_NE(d.message.find("cannot target itself"), std::string::npos);
}

TEST(DemonstrationErrors, TargetWithoutActionValue) {
  const Diagnostic d = firstError(std::string(kHeader) + row(0, "", "G1", "", ""));
  EXPECT_EQ(d.line, 2);
  EXPECT_NE(d.message.find("without an action"), std::string::npos);
}

TEST(DemonstrationErrors, TimeNotStrictlyIncreasing) {
  const Diagnostic d = firstError(std::string(kHeader) + row(0.5, "", "", "", "") + row(0.5, "", "", "", ""));
  EXPECT_EQ(d.line, 3);
  EXPECT_EQ(d.column, 1);
  EXPECT_NE(d.message.find("strictly increasing"), std::string::npos);
}

TEST(DemonstrationErrors, EmptyFileAndHeaderOnly) {
  EXPECT_NE(firstError("").message.find("empty"), std::string::npos);
  EXPECT_NE(firstError("\n\n").message.find("empty"), std::string::npos);
  EXPECT_NE(firstError(kHeader).message.find("no data rows"), std::string::npos);
}

TEST(DemonstrationErrors, NotUtf8) {
  const std::string csv = std::string(kHeader) +
                          "0,0.1,0.1,mo\xff"
                          "ve,G1,0.5,0.5,,,0.2,0.2,0.9,0.9\n";
  const Diagnostic d = firstError(csv);
  EXPECT_EQ(d.line, 2);
  EXPECT_EQ(d.column, 13);
  EXPECT_NE(d.message.find("not UTF-8"), std::string::npos);
}

TEST(DemonstrationErrors, EveryBadRowIsReported) {
  std::string csv =
      std::string(kHeader) + row(0, "fly", "", "", "") + row(1, "", "X", "", "") + row(2, "move", "R1", "", "");
  try {
    parseDemonstrationCsv(csv, scene(), "demo.csv");
    FAIL();
  } catch (const Error& e) {
    ASSERT_EQ(e.diagnostics().size(), 3u) << e.what();
    EXPECT_EQ(e.diagnostics()[2].line, 4);
    EXPECT_EQ(std::string(e.what()).substr(0, 11), "demo.csv:2:");
  }
}

TEST(DemonstrationErrors, CrlfLineEndingsAndByteOrderMarkAreAccepted) {
  std::string csv = "\xEF\xBB\xBF" + std::string(kHeader) + row(0, "move", "G1", "", "");
  for (size_t p = 0; (p = csv.find('\n', p)) != std::string::npos; p += 2) csv.insert(p, "\r");
  EXPECT_NO_THROW(parseDemonstrationCsv(csv, scene(), "demo.csv"));
}

// ---- numbers, line endings, files (inputs are files of bounded size; exact round trips)

namespace {

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "/ddace_demo_" + name;
}

}  // namespace

TEST(DemonstrationErrors, ANumberMustBeTheWholeField) {
  const std::string nul("0.208496\0GARBAGE", 16);
  for (const std::string& bad : {nul, std::string("0.2x"), std::string("0x"), std::string("1e")}) {
    const std::string csv = std::string(kHeader) + "0," + bad + ",0.1,,,0.5,0.5,,,0.2,0.2,0.9,0.9\n";
    const Diagnostic d = firstError(csv);
    EXPECT_EQ(d.line, 2);
    EXPECT_EQ(d.column, 3);
    EXPECT_NE(d.message.find("not a finite number"), std::string::npos) << d.message;
  }
  EXPECT_NE(
      firstError(std::string(kHeader) + "0," + nul + ",0.1,,,0.5,0.5,,,0.2,0.2,0.9,0.9\n").message.find("\\x00GARBAGE"),
      std::string::npos);
}

TEST(Demonstration, CrOnlyCrlfAndLfLineEndingsReadTheSame) {
  std::string lf = std::string(kHeader) + row(0, "move", "G1", "", "") + row(0.1, "move", "G1", "", "") +
                   row(0.2, "", "", "stop", "");
  auto replaced = [&](const std::string& ending) {
    std::string out;
    for (char c : lf) out += c == '\n' ? ending : std::string(1, c);
    return out;
  };
  const TaskSpec spec = scene();
  const std::string expected = demonstrationCsvText(parseDemonstrationCsv(lf, spec, "lf.csv"), spec);
  for (const std::string ending : {"\r", "\r\n"}) {
    const Demonstration d = parseDemonstrationCsv(replaced(ending), spec, "x.csv");
    EXPECT_EQ(d.rows(), 3u);
    EXPECT_EQ(demonstrationCsvText(d, spec), expected);
  }
  // A CR-only file on disk, read as a stream, gives the same.
  writeBytes(tempPath("cr.csv"), replaced("\r"));
  EXPECT_EQ(demonstrationCsvText(readDemonstrationCsv(tempPath("cr.csv"), spec), spec), expected);
}

TEST(Demonstration, StreamingAcrossChunkBoundariesEqualsParsingFromMemory) {
  // Rows of varying length so that line endings (CRLF split between two reads among
  // them) fall on every offset around the 64 KiB read size.
  const TaskSpec spec = scene();
  for (const std::string ending : {"\r\n", "\r", "\n"}) {
    std::string csv = kHeader;
    for (int i = 0; i < 3000; ++i) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%d.%0*d,0.1,0.1,%s,0.5,0.5,,,0.2,0.2,0.9,0.9", i, 1 + i % 7, i % 10,
                    i % 3 ? "move,G1" : ",");
      csv += std::string(buf) + ending;
    }
    writeBytes(tempPath("stream.csv"), csv);
    const Demonstration a = parseDemonstrationCsv(csv, spec, "m.csv");
    const Demonstration b = readDemonstrationCsv(tempPath("stream.csv"), spec);
    EXPECT_EQ(a.rows(), 3000u);
    EXPECT_EQ(a.t, b.t);
    EXPECT_EQ(a.labels, b.labels);
    EXPECT_EQ(a.keyframes, b.keyframes);
  }
}

TEST(Demonstration, WrittenNumbersReadBackExactly) {
  // Property: any finite t (strictly increasing) and positions survive write -> read
  // bit for bit, and writing again gives the same bytes.
  const TaskSpec spec = scene();
  SplitMix64 rng(12345);
  for (int trial = 0; trial < 50; ++trial) {
    Demonstration d;
    d.has_label_columns = {true, true, false, false};
    double t = trial == 0 ? 0.0 : rng.uniform(-1e3, 1e3);
    for (int r = 0; r < 20; ++r) {
      d.t.push_back(t);
      // Tiny steps (t = 0, 1e-7, ...), ordinary ones, and ones at the limit of doubles.
      t = trial % 3 == 0 ? t + 1e-7 : trial % 3 == 1 ? t + rng.uniform(1e-3, 1.0) : std::nextafter(t, 1e300);
      std::vector<Eigen::Vector2d> pos;
      for (int e = 0; e < 4; ++e) {
        const double scale = std::pow(10.0, rng.uniform(-300, 300));
        pos.emplace_back((rng.uniform() - 0.5) * scale, rng.uniform(-2, 2));
      }
      d.positions.push_back(pos);
      std::vector<Label> labels(4);
      if (r % 5 == 1) labels[0] = {"move", 3};
      d.labels.push_back(labels);
    }
    const std::string text = demonstrationCsvText(d, spec);
    const Demonstration back = parseDemonstrationCsv(text, spec, "p.csv");
    ASSERT_EQ(back.t, d.t) << text.substr(0, 400);
    ASSERT_EQ(back.positions, d.positions);
    EXPECT_EQ(back.labels, d.labels);
    EXPECT_EQ(demonstrationCsvText(back, spec), text);
  }
  // Micrometres and 20 Hz times keep their six decimals.
  std::string csv = kHeader;
  csv += row(0.05, "", "", "", "", 0.123457);
  EXPECT_EQ(demonstrationCsvText(parseDemonstrationCsv(csv, spec, "a.csv"), spec).substr(std::string(kHeader).size()),
            "0.050000,0.123457,0.100000,,,0.500000,0.500000,,,0.200000,0.200000,0.900000,0.900000\n");
}

TEST(DemonstrationFiles, OnlyRegularFilesAreReadAndNothingHangs) {
  const TaskSpec spec = scene();
  const std::string fifo = tempPath("fifo.csv");
  std::remove(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string a = tempPath("loop_a.csv"), b = tempPath("loop_b.csv");
  std::remove(a.c_str());
  std::remove(b.c_str());
  ASSERT_EQ(::symlink(b.c_str(), a.c_str()), 0);
  ASSERT_EQ(::symlink(a.c_str(), b.c_str()), 0);
  for (const auto& [path, why] :
       std::vector<std::pair<std::string, std::string>>{{fifo, "FIFO"},
                                                        {a, "symbolic links"},
                                                        {"/dev/zero", "character device"},
                                                        {::testing::TempDir(), "directory"}}) {
    try {
      readDemonstrationCsv(path, spec);
      ADD_FAILURE() << path;
    } catch (const Error& e) {
      EXPECT_EQ(e.diagnostics().at(0).file, path);
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  }
  std::remove(fifo.c_str());
  std::remove(a.c_str());
  std::remove(b.c_str());
}

TEST(DemonstrationFiles, AnOverlongLineIsRefusedWithoutHoldingIt) {
  writeBytes(tempPath("long.csv"), std::string(kHeader) + std::string(3 << 20, '7') + "\n");
  try {
    readDemonstrationCsv(tempPath("long.csv"), scene());
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("long.csv:2:1: line longer than"), std::string::npos) << e.what();
  }
}

TEST(DemonstrationFiles, AFailedWriteIsAnErrorNamingTheFileAndLeavesNothingBehind) {
  std::string csv = std::string(kHeader) + row(0, "move", "G1", "", "");
  const TaskSpec spec = scene();
  const Demonstration d = parseDemonstrationCsv(csv, spec, "a.csv");
  try {
    writeDemonstrationCsv(d, spec, "/dev/full");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.diagnostics().at(0).file, "/dev/full");
    EXPECT_NE(std::string(e.what()).find("No space left"), std::string::npos) << e.what();
  }
  // A directory that does not exist: an error, no file.
  EXPECT_THROW(writeDemonstrationCsv(d, spec, tempPath("missing_dir/x.csv")), Error);
  // A good write replaces the file in one step.
  const std::string path = tempPath("written.csv");
  writeBytes(path, "old");
  writeDemonstrationCsv(d, spec, path);
  EXPECT_EQ(demonstrationCsvText(readDemonstrationCsv(path, spec), spec), demonstrationCsvText(d, spec));
}

namespace {

/// The grouping rule written out directly over all rows (as docs/task-format.md states
/// it): for each row, the tokens that begin there join the open step when every token of
/// the step still holds in that row.
std::vector<std::vector<Token>> referenceSteps(const Demonstration& d) {
  std::vector<std::vector<Token>> steps;
  std::vector<int> last_rows;  // of the open step's tokens
  const std::vector<Label> none(d.entities());
  for (size_t i = 0; i < d.rows(); ++i) {
    const auto& prev = i == 0 ? none : d.labels[i - 1];
    std::vector<Token> starting;
    std::vector<int> ends;
    for (size_t e = 0; e < d.entities(); ++e) {
      const Label& l = d.labels[i][e];
      if (l.isNull() || l == prev[e]) continue;
      size_t last = i;
      while (last + 1 < d.rows() && d.labels[last + 1][e] == l) ++last;
      starting.push_back({static_cast<int>(e), l.action, l.target});
      ends.push_back(static_cast<int>(last));
    }
    if (starting.empty()) continue;
    bool holds = !steps.empty();
    for (int last : last_rows) holds = holds && last >= static_cast<int>(i);
    if (!holds) {
      steps.emplace_back();
      last_rows.clear();
    }
    steps.back().insert(steps.back().end(), starting.begin(), starting.end());
    std::sort(steps.back().begin(), steps.back().end());
    last_rows.insert(last_rows.end(), ends.begin(), ends.end());
  }
  return steps;
}

}  // namespace

TEST(DemonstrationFiles, ASummaryIsWhatReadingDerivesWithoutTheRows) {
  // Random labels (late onsets, early ends, switches, one-row tokens): the summary read
  // without rows equals what analyze() derives from the stored rows.
  SplitMix64 rng(99);
  const char* actions[] = {"", "move", "carry", "stop"};
  const char* targets[] = {"G1", "B1"};
  {
    const TaskSpec spec = scene();
    for (int trial = 0; trial < 60; ++trial) {
      std::string csv = kHeader;
      std::string a1, t1, a2, t2;
      for (int r = 0; r < 60; ++r) {
        if (rng.uniform() < 0.2) {
          a1 = actions[rng.index(4)];
          t1 = a1.empty() || a1 == "stop" ? "" : targets[rng.index(2)];
        }
        if (rng.uniform() < 0.2) {
          a2 = actions[rng.index(4)];
          t2 = a2.empty() || a2 == "stop" ? "" : targets[rng.index(2)];
        }
        csv += row(0.1 * r, a1, t1, a2, t2, 0.01 * r);
      }
      const std::string path = tempPath("summary.csv");
      writeBytes(path, csv);
      const Demonstration d = readDemonstrationCsv(path, spec);
      const DemonstrationSummary s = summarizeDemonstrationCsv(path, spec);
      const std::vector<std::vector<Token>> expected = referenceSteps(d);
      ASSERT_EQ(d.steps.size(), expected.size()) << csv;
      for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(d.steps[k].tokens, expected[k]) << csv;
      EXPECT_EQ(s.source, path);
      EXPECT_EQ(s.rows, d.rows());
      EXPECT_EQ(s.t_first, d.t.front());
      EXPECT_EQ(s.t_last, d.t.back());
      EXPECT_EQ(s.segments, d.segments.size());
      EXPECT_EQ(s.end_row, d.snapshots.back().row);
      ASSERT_EQ(s.steps.size(), d.steps.size());
      ASSERT_EQ(s.keyframe_t.size(), d.steps.size());
      for (size_t k = 0; k < d.steps.size(); ++k) {
        EXPECT_EQ(s.steps[k].keyframe_row, d.steps[k].keyframe_row);
        EXPECT_EQ(s.keyframe_t[k], d.t[d.steps[k].keyframe_row]);
        EXPECT_EQ(s.steps[k].tokens, d.steps[k].tokens);
        ASSERT_EQ(s.steps[k].late.size(), d.steps[k].late.size());
        for (size_t j = 0; j < d.steps[k].late.size(); ++j) EXPECT_EQ(s.steps[k].late[j].row, d.steps[k].late[j].row);
      }
      EXPECT_EQ(stepGroupingNotes(s.source, s.steps, spec).size(), stepGroupingNotes(d, spec).size());
      // Counting only (ddace label's read-back of a long recording): the same counts, the last step.
      const DemonstrationSummary c = summarizeDemonstrationCsv(path, spec, false);
      EXPECT_EQ(s.step_count, d.steps.size());
      EXPECT_EQ(c.step_count, d.steps.size());
      EXPECT_EQ(c.segments, d.segments.size());
      EXPECT_EQ(c.rows, d.rows());
      ASSERT_EQ(c.steps.size(), d.steps.empty() ? 0u : 1u);
      if (!d.steps.empty()) {
        EXPECT_EQ(c.steps[0].keyframe_row, d.steps.back().keyframe_row);
        EXPECT_EQ(c.steps[0].tokens, d.steps.back().tokens);
      }
    }
  }
  // The same errors as reading.
  writeBytes(tempPath("bad_summary.csv"), std::string(kHeader) + row(0, "fly", "G1", "", ""));
  EXPECT_THROW(summarizeDemonstrationCsv(tempPath("bad_summary.csv"), scene()), Error);
}

namespace {

/// Steps from token lists: {{"0:move:2", "1:move:3"}, {"2:move:4"}} (entity:action:target).
std::vector<Step> stepsOf(const std::vector<std::vector<std::string>>& keys) {
  std::vector<Step> out;
  for (const auto& step : keys) {
    Step s;
    for (const auto& k : step) {
      Token t;
      const size_t a = k.find(':'), b = k.rfind(':');
      t.entity = std::stoi(k.substr(0, a));
      t.action = k.substr(a + 1, b - a - 1);
      t.target = std::stoi(k.substr(b + 1));
      s.tokens.push_back(t);
    }
    std::sort(s.tokens.begin(), s.tokens.end());
    out.push_back(s);
  }
  return out;
}

}  // namespace

// "Fixed order" tolerates labelling slips: at most one demonstration in ten whose steps
// differ from all the others' in one token of one entity; anything else varies.
TEST(CommonSteps, AFewOneTokenSlipsKeepTheStepsFixedAndAreListed) {
  const auto usual = stepsOf({{"0:move:2", "1:move:3"}, {"2:move:4"}});
  const auto slip = stepsOf({{"0:move:3", "1:move:3"}, {"2:move:4"}});  // entity 0's target
  std::vector<std::vector<Step>> demos(9, usual);
  EXPECT_TRUE(commonSteps(demos).fixed);
  EXPECT_TRUE(commonSteps(demos).slips.empty());
  // 9 demonstrations: no slip allowed (fewer than ten).
  demos.back() = slip;
  EXPECT_FALSE(commonSteps(demos).fixed);
  // 10: one.
  demos.push_back(usual);
  const CommonSteps c = commonSteps(demos);
  ASSERT_TRUE(c.fixed);
  EXPECT_TRUE(sameSteps(c.steps, usual));
  ASSERT_EQ(c.slips.size(), 1u);
  EXPECT_EQ(c.slips[0].demo, 8u);
  EXPECT_EQ(c.slips[0].step, 0u);
  EXPECT_EQ(c.slips[0].token.target, 3);
  EXPECT_EQ(c.slips[0].expected.target, 2);
  // Two slips in ten: more than one in ten.
  demos[0] = slip;
  EXPECT_FALSE(commonSteps(demos).fixed);
  demos[0] = usual;
  // Not slips: two tokens changed, another entity acting, a step more or less.
  for (const auto& other :
       {stepsOf({{"0:move:3", "1:move:2"}, {"2:move:4"}}), stepsOf({{"0:move:2", "4:move:3"}, {"2:move:4"}}),
        stepsOf({{"0:move:2", "1:move:3"}, {"2:move:4"}, {"3:move:4"}}), stepsOf({{"0:move:2", "1:move:3"}})}) {
    demos[8] = other;
    EXPECT_FALSE(commonSteps(demos).fixed);
  }
  // Where the scene decides, the steps vary in many ways: never fixed.
  std::vector<std::vector<Step>> scene;
  for (int i = 0; i < 20; ++i) scene.push_back(stepsOf({{"0:move:" + std::to_string(2 + i % 2)}}));
  EXPECT_FALSE(commonSteps(scene).fixed);
}

// ---- step grouping across demonstrations (docs/task-format.md, "Step grouping", rule 6)

namespace {

const char* kSceneYaml =
    "format: ddace-task/1\nentities:\n"
    "  - {name: R1, kind: robot}\n  - {name: R2, kind: robot}\n"
    "  - {name: B1, kind: object}\n  - {name: G1, kind: goal}\n"
    "actions: [move, carry, stop]\n";

/// R1 moves to G1 and R2 to `r2_target`, started together (one step) or R2 after R1 has
/// stopped (two steps by rule 4).
std::string pairCsv(bool together, const std::string& r2_target = "B1") {
  std::string csv = kHeader;
  if (together) {
    csv += row(0.0, "move", "G1", "move", r2_target, 0.1);
    csv += row(0.1, "move", "G1", "move", r2_target, 0.2);
    csv += row(0.2, "", "", "move", r2_target, 0.3);
    csv += row(0.3, "", "", "", "", 0.3);
  } else {
    csv += row(0.0, "move", "G1", "", "", 0.1);
    csv += row(0.1, "move", "G1", "", "", 0.2);
    csv += row(0.2, "", "", "move", r2_target, 0.3);
    csv += row(0.3, "", "", "move", r2_target, 0.3);
    csv += row(0.4, "", "", "", "", 0.3);
  }
  return csv;
}

/// A task directory of demonstrations demo_000.csv, ... with `csvs`.
std::string pairDir(const std::string& name, const std::vector<std::string>& csvs) {
  const std::string dir = tempPath("across_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/demos");
  writeBytes(dir + "/task.yaml", kSceneYaml);
  for (size_t i = 0; i < csvs.size(); ++i) writeBytes(dir + "/demos/demo_00" + std::to_string(i) + ".csv", csvs[i]);
  return dir;
}

std::vector<size_t> stepCounts(const TaskDir& dir) {
  std::vector<size_t> n;
  for (const auto& d : dir.demos) n.push_back(d.steps.size());
  return n;
}

}  // namespace

TEST(StepGroupingAcrossDemonstrations, AStepSplitWhereTheOthersShowOneIsMergedAndListed) {
  // Two demonstrations start R1 and R2 together; in the third R2 set off after R1 had
  // stopped. The two share no entity and the others show them as one step: one step.
  const std::string dir = pairDir("split", {pairCsv(true), pairCsv(true), pairCsv(false)});
  const TaskSpec spec = readTaskYaml(dir + "/task.yaml");
  EXPECT_EQ(readDemonstrationCsv(dir + "/demos/demo_002.csv", spec).steps.size(), 2u);  // on its own
  const TaskDir loaded = loadTaskDir(dir);
  EXPECT_EQ(stepCounts(loaded), (std::vector<size_t>{1, 1, 1}));
  const Demonstration& d = loaded.demos[2];
  EXPECT_TRUE(sameSteps(d.steps, loaded.demos[0].steps));
  EXPECT_EQ(d.keyframes, (std::vector<int>{0}));
  ASSERT_EQ(d.snapshots.size(), 2u);  // the step's, END
  EXPECT_EQ(d.snapshots[0].row, 0);
  EXPECT_TRUE(d.snapshots[1].end);
  ASSERT_EQ(d.segments.size(), 2u);
  EXPECT_EQ(d.segments[1].step, 0);
  EXPECT_EQ(d.segments[1].first_row, 2);                    // R2's own rows
  EXPECT_DOUBLE_EQ(d.segmentGoal(d.segments[1]).x(), 0.2);  // B1 where the step was decided
  // validate's summary reads the same steps and lists the merge.
  const TaskDirSummary summary = summarizeTaskDir(dir);
  ASSERT_EQ(summary.demos.size(), 3u);
  EXPECT_EQ(summary.demos[2].step_count, 1u);
  EXPECT_EQ(summary.demos[2].keyframe_t, (std::vector<double>{0.0}));
  EXPECT_TRUE(sameSteps(summary.demos[2].steps, d.steps));
  const std::vector<Diagnostic> notes = stepGroupingNotes(summary.demos[2].source, summary.demos[2].steps, spec);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0].str(), dir +
                                "/demos/demo_002.csv:4: step 1: [R2:move:B1] began after a token of step 1 (line 2) "
                                "had ended, a step of its own in this demonstration; merged into step 1 as 2 of 3 "
                                "demonstrations show such tokens in one step: check that they are one");
  EXPECT_EQ(stepGroupingNotes(d, spec).size(), 1u);
}

TEST(StepGroupingAcrossDemonstrations, StepsSharingAnEntityOrShownApartStayApart) {
  // R2 sent to R1 shares R1 with R1's step: never merged, whatever the others show.
  EXPECT_EQ(
      stepCounts(loadTaskDir(pairDir("shared", {pairCsv(true, "R1"), pairCsv(true, "R1"), pairCsv(false, "R1")}))),
      (std::vector<size_t>{1, 1, 2}));
  // Most demonstrations show two steps: the one step of the third stays one, the two stay two.
  EXPECT_EQ(stepCounts(loadTaskDir(pairDir("apart", {pairCsv(false), pairCsv(false), pairCsv(true)}))),
            (std::vector<size_t>{2, 2, 1}));
  // As many show one step as two: no evidence either way.
  EXPECT_EQ(stepCounts(loadTaskDir(pairDir("even", {pairCsv(true), pairCsv(false)}))), (std::vector<size_t>{1, 2}));
}
