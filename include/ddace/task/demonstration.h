// One demonstration: a CSV of ddace-task/1 and what the spec derives from it
// (keyframes, steps and their tokens, segments, graph snapshots with the
// terminal END snapshot). See shared/spec/task-format.md, "Semantics".
//
// Positions are metres in the table frame; times are seconds from the start.
// Rows are 0-based indices into the data rows (file line = row + 2).
#pragma once

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
  bool operator==(const Token& o) const {
    return entity == o.entity && action == o.action && target == o.target;
  }
  bool operator!=(const Token& o) const { return !(*this == o); }
  bool operator<(const Token& o) const;
};

/// "R1:move:R3", or "R1:stop" for an in-place action. Also the motion primitive key.
std::string tokenKey(const Token& token, const TaskSpec& spec);
/// Parses tokenKey() output. Throws ddace::Error naming the bad part.
Token parseTokenKey(const std::string& key, const TaskSpec& spec);

/// Step k: the tokens that begin at keyframe k, sorted by entity index.
struct Step {
  int keyframe_row = 0;
  std::vector<Token> tokens;
};

/// The rows during which a token's label holds: [first_row, last_row].
struct Segment {
  Token token;
  int step = 0;       ///< index of the step that started it
  int first_row = 0;  ///< the step's keyframe row
  int last_row = 0;   ///< last row before the entity's label changes away
};

/// Positions of all entities at one row; the state in which a step was decided.
struct Snapshot {
  int row = 0;
  bool end = false;  ///< the terminal snapshot (last row), labelled END
  std::vector<Eigen::Vector2d> positions;  ///< [entity], metres
};

class Demonstration {
 public:
  std::string source;                                  ///< file it was read from (diagnostics)
  std::vector<double> t;                               ///< [row], seconds
  std::vector<std::vector<Eigen::Vector2d>> positions; ///< [row][entity], metres
  std::vector<std::vector<Label>> labels;              ///< [row][entity]
  std::vector<bool> has_label_columns;                 ///< [entity]
  /// Step grouping window, seconds >= 0 (task.yaml's step_window_s; the generators set it
  /// from the task).
  double step_window_s = kDefaultStepWindow;

  // Derived by analyze(); filled by the readers and the generators.
  std::vector<int> keyframes;       ///< rows that are keyframes
  std::vector<Step> steps;          ///< one per keyframe
  std::vector<Segment> segments;    ///< one per token, in step order
  std::vector<Snapshot> snapshots;  ///< one per step plus the END snapshot

  size_t rows() const { return t.size(); }
  size_t entities() const { return has_label_columns.size(); }

  /// Computes keyframes, steps, segments and snapshots from t/positions/labels.
  void analyze();
  /// Positions of the segment's entity over its rows.
  std::vector<Eigen::Vector2d> segmentPath(const Segment& segment) const;
  /// Goal of a motion segment: the target's position at the step's keyframe.
  Eigen::Vector2d segmentGoal(const Segment& segment) const;
};

/// Parses CSV text against `spec`. `file` is used in diagnostics. Throws
/// ddace::Error listing every problem (file:line:column); the result is analyzed.
Demonstration parseDemonstrationCsv(const std::string& text, const TaskSpec& spec,
                                    const std::string& file);
/// Reads, parses and analyzes one CSV. Throws ddace::Error.
Demonstration readDemonstrationCsv(const std::string& path, const TaskSpec& spec);
/// CSV text: t, then per entity <E>.x,<E>.y and, where present, <E>.action,<E>.target.
/// Numbers with 6 decimals (micrometres); byte-identical for identical input.
std::string demonstrationCsvText(const Demonstration& demo, const TaskSpec& spec);
void writeDemonstrationCsv(const Demonstration& demo, const TaskSpec& spec,
                           const std::string& path);

}  // namespace ddace::task
