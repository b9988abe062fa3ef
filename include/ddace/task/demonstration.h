// One demonstration: a CSV of ddace-task/1 and what the format derives from it
// (steps and their tokens after step grouping, segments, graph snapshots with the
// terminal END snapshot). See docs/task-format.md, "Semantics".
//
// Positions are metres in the table frame; times are seconds from the start.
// Rows are 0-based indices into the data rows (file line = row + 2 for the files
// the project writes; a reader records the line of every row it read).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/task/task_spec.h"

namespace ddace::task {

/// The label of one entity in one row. Null when the action is idle or empty.
struct Label {
  std::string action;  ///< empty for idle / none
  int target = -1;     ///< entity index, -1 for none
  bool isNull() const { return action.empty(); }
  bool operator==(const Label& o) const { return action == o.action && target == o.target; }
  bool operator!=(const Label& o) const { return !(*this == o); }
};

/// (entity, action, target): what one entity starts doing in a step.
struct Token {
  int entity = -1;     ///< entity index
  std::string action;  ///< never empty
  int target = -1;     ///< entity index, -1 for an in-place action
  bool isMotion() const { return target >= 0; }
  bool operator==(const Token& o) const { return entity == o.entity && action == o.action && target == o.target; }
  bool operator!=(const Token& o) const { return !(*this == o); }
  bool operator<(const Token& o) const;
};

/// "R1:move:R3", or "R1:stop" for an in-place action. Also the motion primitive key.
std::string tokenKey(const Token& token, const TaskSpec& spec);
/// Parses tokenKey() output. Throws ddace::Error naming the bad part.
Token parseTokenKey(const std::string& key, const TaskSpec& spec);

/// A token whose label began after its step's first row and joined the step (step grouping).
struct LateOnset {
  Token token;
  int row = 0;         ///< row where its label begins
  double delay_s = 0;  ///< t[row] - t[keyframe_row], seconds, > 0
};

/// A step that began while a token of the step before still ran, after another token of
/// that step had ended: a step of its own by the rule, which the person may have meant for
/// the step before (started after a shorter token of it ended).
struct StepOverlap {
  Token ended;        ///< the first token of the step before to end
  int ended_row = 0;  ///< its last row: a token beginning by this row joins that step
  Token running;      ///< a token of the step before still running at this step's keyframe
};

/// A step of its own by the rule in its demonstration that the task's other demonstrations
/// show as part of the step before (stepsShownAsOne): merged into that step.
struct MergedStep {
  int keyframe_row = 0;       ///< its own first row
  std::vector<Token> tokens;  ///< its tokens, sorted
  size_t shown_by = 0;        ///< demonstrations whose steps show the merged step
  size_t demonstrations = 0;  ///< of the task's
};

/// Step k: the tokens that begin at keyframe k or join it while every token of it still
/// runs (docs/task-format.md, "Step grouping"), sorted by entity index.
struct Step {
  int keyframe_row = 0;  ///< the row of the step's first token: its snapshot
  std::vector<Token> tokens;
  std::vector<LateOnset> late;         ///< the tokens that joined after keyframe_row, in row order
  std::optional<StepOverlap> overlap;  ///< set when it began while the step before ran
  std::vector<MergedStep> merged;      ///< steps after it merged into it, in row order (tokens among `tokens`)
};

/// The same number of steps with the same tokens, step by step (keyframe rows and late
/// onsets aside): two demonstrations of one fixed step order.
bool sameSteps(const std::vector<Step>& a, const std::vector<Step>& b);

/// A labelling slip: a demonstration whose steps are the others' but for one token, the
/// same entity labelled with another action or target.
struct StepSlip {
  size_t demo = 0;  ///< index of the demonstration
  size_t step = 0;  ///< 0-based step index
  Token token;      ///< as labelled
  Token expected;   ///< as in the other demonstrations
};
/// What the demonstrations' steps have in common. `fixed`: every demonstration has the most
/// common step sequence, `steps`, except at most one in ten of them (rounded down: none of
/// fewer than ten), each of those different in a single token (a slip, listed in `slips`).
/// Unset when the steps vary otherwise: the scene decided them (docs/tgn.md, "Fixed order").
struct CommonSteps {
  bool fixed = false;
  std::vector<Step> steps;
  std::vector<StepSlip> slips;
};
/// `steps_of`: every demonstration's steps, in order (at least one demonstration).
CommonSteps commonSteps(const std::vector<std::vector<Step>>& steps_of);

/// Consecutive steps of one demonstration to be read as one: steps first..last.
struct StepRun {
  size_t first = 0, last = 0;
  size_t shown_by = 0;        ///< demonstrations whose steps show them as one
  size_t demonstrations = 0;  ///< of the task's
};
/// Step grouping across demonstrations (docs/task-format.md, "Step grouping", rule 6):
/// per demonstration of `steps_of` (one task's, each grouped on its own), the runs of
/// consecutive steps whose tokens share no entity (mover or target) that more of the
/// demonstrations show as one step than show the demonstration's own steps. Steps are
/// compared by the kinds of their tokens (action, the kind and type of mover and target),
/// not the names: the scene may choose other entities in each demonstration.
std::vector<std::vector<StepRun>> stepsShownAsOne(const std::vector<std::vector<Step>>& steps_of, const TaskSpec& spec);
/// `steps` with each run merged into its first step: the later steps' tokens join it
/// (as Step::merged records), their keyframes go. `runs` as stepsShownAsOne gives them.
std::vector<Step> mergedSteps(const std::vector<Step>& steps, const std::vector<StepRun>& runs);

/// The rows during which a token's label holds: [first_row, last_row].
struct Segment {
  Token token;
  int step = 0;       ///< index of the step it belongs to
  int first_row = 0;  ///< the token's own first row (the step's keyframe unless it joined late)
  int last_row = 0;   ///< last row before the entity's label changes away
};

/// Positions of all entities at one row; the state in which a step was decided.
struct Snapshot {
  int row = 0;
  bool end = false;                        ///< the terminal snapshot (last row), labelled END
  std::vector<Eigen::Vector2d> positions;  ///< [entity], metres
};

class Demonstration {
 public:
  std::string source;                                   ///< file it was read from (diagnostics)
  std::vector<double> t;                                ///< [row], seconds
  std::vector<std::vector<Eigen::Vector2d>> positions;  ///< [row][entity], metres
  std::vector<std::vector<Label>> labels;               ///< [row][entity]
  std::vector<bool> has_label_columns;                  ///< [entity]
  // Derived by analyze(); filled by the readers and the generators.
  std::vector<int> keyframes;       ///< keyframe row of every step
  std::vector<Step> steps;          ///< one per keyframe
  std::vector<Segment> segments;    ///< one per token, in step order
  std::vector<Snapshot> snapshots;  ///< one per step plus the END snapshot

  size_t rows() const { return t.size(); }
  size_t entities() const { return has_label_columns.size(); }

  /// Computes steps (step grouping), keyframes, segments and snapshots
  /// from t/positions/labels. t must be strictly increasing.
  void analyze();
  /// Merges runs of steps (stepsShownAsOne) into their first step: steps, keyframes,
  /// the segments' step indices and the snapshots follow (the run's first keyframe stays).
  void mergeSteps(const std::vector<StepRun>& runs);
  /// Positions of the segment's entity over its rows.
  std::vector<Eigen::Vector2d> segmentPath(const Segment& segment) const;
  /// Goal of a motion segment: the target's position at its step's keyframe (when the
  /// step was decided); for an in-place action, the entity's own position there.
  Eigen::Vector2d segmentGoal(const Segment& segment) const;
};

/// Step grouping's notes for `ddace validate` (line = row + 2: the header is line 1): one per
/// token merged into its step, "<source>:<line>: step k: R2:move:G1 began 0.250 s after
/// the step's first token (line L); merged into the step", and one per step that began
/// while the step before still ran (Step::overlap), "<source>:<line>: step k: R2:move:G1
/// began while R1:move:G2 of step k-1 still ran, after R3:move:B1 of it had ended (line L):
/// a step of its own (...; begin its label by line L if it belongs to step k-1)", and one
/// per step merged into the step before by the other demonstrations' evidence
/// (Step::merged), "<source>:<line>: step k: [R2:move:B2] ... merged into step k, as 18 of
/// 20 demonstrations show ...: check it".
std::vector<Diagnostic> stepGroupingNotes(const Demonstration& demo, const TaskSpec& spec);

/// The largest demonstration CSV readDemonstrationCsv accepts: 1 GiB. It reads it as a
/// stream, never holding its text, but keeps the parsed rows (about 90 bytes per entity
/// and row); summarizeDemonstrationCsv (task/summary.h) keeps none of them and reads a
/// file of any length.
inline constexpr std::uint64_t kMaxDemonstrationBytes = std::uint64_t{1} << 30;

/// Parses CSV text against `spec`. `file` is used in diagnostics. Throws
/// ddace::Error listing every problem (file:line:column); the result is analyzed.
Demonstration parseDemonstrationCsv(const std::string& text, const TaskSpec& spec, const std::string& file);
/// Reads, parses and analyzes one CSV, as a stream. Throws ddace::Error naming the file
/// when it is not a regular file (a FIFO, a device, a directory, a symlink loop: refused
/// before it is opened), is larger than kMaxDemonstrationBytes, or has errors.
Demonstration readDemonstrationCsv(const std::string& path, const TaskSpec& spec);
/// CSV text: t, then per entity <E>.x,<E>.y and, where present, <E>.action,<E>.target.
/// A number is written with 6 decimals when that reads back exactly (micrometres, 20 or
/// 30 Hz times), else with the shortest digits that do: every value reads back as it
/// was. Byte-identical for identical input.
std::string demonstrationCsvText(const Demonstration& demo, const TaskSpec& spec);
/// Writes demonstrationCsvText() checked and atomically (common/file.h OutputFile):
/// a failed write throws ddace::Error naming `path` and leaves no half-written file.
void writeDemonstrationCsv(const Demonstration& demo, const TaskSpec& spec, const std::string& path);

}  // namespace ddace::task
