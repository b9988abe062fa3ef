// Tokens and steps inferred from a demonstration's motion (docs/labels.md), with action
// words from a hand-labelled example, and everything the motion does not decide surely
// reported as a note on the row where it happens.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "ddace/label/inference.h"
#include "ddace/task/demonstration.h"

namespace ddace::label {

/// One inferred token and the rows its label holds (the step's first onset to its own end).
struct InferredToken {
  task::Token token;
  int first_row = 0, last_row = 0;
  int onset_row = 0;      ///< where the entity itself started to move (the step's keyframe for in-place)
  int carrier = -1;       ///< for a load: the entity that carried it
  int load = 0;           ///< 1: it carried a load, 2: it was one (kindKey)
  bool in_place = false;  ///< an in-place action taken from the example
  std::vector<int> tied;  ///< the entities its end point could not tell apart (target among them)
  std::string kind;       ///< kindKey(): what decides its word
};

struct InferredStep {
  int keyframe_row = 0;
  std::vector<InferredToken> tokens;  ///< by entity
};

/// Something the motion did not decide surely, at a row (file line = row + 2).
struct Note {
  int row = 0;
  std::string message;
};

struct Inference {
  std::vector<InferredStep> steps;
  std::vector<Note> notes;  ///< in row order
};

/// The kind of a motion, which decides its action word: mover kind/type, target
/// kind/type, and whether it carried a load ("+load") or was one ("+carried").
std::string kindKey(const task::TaskSpec& spec, int mover, int target, int load);
/// The same without the types: the fallback when the example has no motion of the exact kind.
std::string coarseKindKey(const task::TaskSpec& spec, int mover, int target, int load);

/// What a demonstration labelled by hand teaches (`ddace label --example`): the word of
/// every kind of motion, its steps (so a demonstration whose motion has the example's
/// steps gets its in-place actions and its choice between entities stacked on one spot),
/// and which kind of entity it chose when an end point was a tie.
struct Example {
  std::string source;
  std::map<std::string, std::string> words;          ///< kindKey / coarseKindKey -> action
  std::vector<task::Step> steps;                     ///< as labelled
  std::map<std::string, task::EntityKind> tie_kind;  ///< tied kinds ("goal,object,robot") -> chosen
  /// Reads the example's words off its own motion and labels. Throws ddace::Error naming
  /// `d.source` when it has no labelled motion.
  static Example fromDemonstration(const task::Demonstration& d, const task::TaskSpec& spec);
};

/// Infers the labels of one demonstration, row by row.
class Labeller {
 public:
  explicit Labeller(const task::TaskSpec& spec, const Example* example = nullptr);
  void row(double t, const std::vector<Eigen::Vector2d>& positions);
  /// The steps and notes; call once after the last row.
  Inference finish();
  int rows() const { return segmenter_.rows(); }

 private:
  const task::TaskSpec& spec_;
  const Example* example_;
  SegmentationOptions options_;
  MotionSegmenter segmenter_;
  std::vector<Motion> motions_;
};

/// inferLabels over a demonstration in memory.
Inference inferLabels(const task::Demonstration& d, const task::TaskSpec& spec, const Example* example = nullptr);

/// The label of every entity row by row, from an inference (for writing a recording as a
/// stream): call at(row) with increasing rows.
class LabelCursor {
 public:
  LabelCursor(const Inference& inference, size_t entities);
  const std::vector<task::Label>& at(int row);

 private:
  struct Span {
    int first, last, entity;
    task::Label label;
  };
  std::vector<Span> spans_;  ///< by first row
  size_t next_ = 0;
  std::vector<Span> open_;
  std::vector<task::Label> labels_;
};

/// Replaces `d`'s labels by the inference's (label columns for every entity with a
/// token) and analyzes it again.
void applyLabels(task::Demonstration& d, const Inference& inference);

/// True when `d` has no labels: no label columns, or every action idle or empty.
bool unlabelled(const task::Demonstration& d);

}  // namespace ddace::label
