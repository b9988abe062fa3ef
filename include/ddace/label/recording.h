// Labelling a recording as a stream (`ddace label`): memory independent of its length.
// Pass 1 feeds its rows to a Labeller, which hands over steps as they are decided (kept
// on disk in a TokenSpill); pass 2 copies the file with the inferred labels. The file is
// checked first with the task module's own reader (task/summary.h), so these passes see
// only a valid ddace-task/1 CSV; a file that changed in between is an error. A recording
// of any size is read (no byte limit: nothing of it is held).
#pragma once

#include <cstdio>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/label/label.h"

namespace ddace::label {

/// Calls `row(line, t, positions)` for every data row of the CSV at `path` (a file that
/// task::summarizeDemonstrationCsv accepted), reading it as a stream. Throws ddace::Error
/// "path:line:column: ..." when a row does not read (the file changed since it was checked).
void forEachRow(const std::string& path, const task::TaskSpec& spec,
                const std::function<void(int line, double t, const std::vector<Eigen::Vector2d>& positions)>& row);

/// What pass 1 found in a recording; its steps and notes went to the callbacks.
struct RecordingInference {
  size_t rows = 0, steps = 0, tokens = 0, notes = 0;
  std::vector<bool> labelled;  ///< [entity] it has a token (its label columns are written)
};

/// Pass 1, streamed: `on_step` gets every step as soon as it is decided (in row order),
/// `on_note` its notes (in row order within a step's time; a note's file line is
/// row + 2). Memory: a few seconds of rows and motions (Labeller), never the steps.
RecordingInference inferRecording(const std::string& path, const task::TaskSpec& spec, const Example* example,
                                  const std::function<void(InferredStep&&)>& on_step,
                                  const std::function<void(Note&&)>& on_note);
/// Pass 1 keeping every step and note (a recording of a session, the recorder node).
Inference inferRecording(const std::string& path, const task::TaskSpec& spec, const Example* example);

/// The tokens of inferred steps kept on disk between the passes: an unnamed temporary
/// file (tmpfile(3), gone when closed), 20 bytes per token, read back in the order
/// written. One spill holds the tokens of several recordings one after the other.
class TokenSpill {
 public:
  TokenSpill();  ///< throws ddace::Error when no temporary file can be made
  ~TokenSpill();
  TokenSpill(const TokenSpill&) = delete;
  TokenSpill& operator=(const TokenSpill&) = delete;

  void add(const InferredStep& step);
  /// Tokens written so far: recording i's are [its size() before pass 1, after pass 1).
  size_t size() const { return written_; }
  /// Reads tokens [from, to) back as spans of LabelCursor (call it once per range).
  std::function<bool(LabelCursor::Span&)> reader(size_t from, size_t to);

 private:
  std::FILE* file_ = nullptr;
  size_t written_ = 0;
  std::vector<std::string> actions_;  ///< the action words seen (a record holds an index)
};

/// Writes the CSV at `path` with `labels`' labels to `out` (pass 2): t and positions as
/// the file holds them (same digits), label columns for every entity `labelled`, none of
/// the file's own (empty) label columns.
void writeLabelledRecording(const std::string& path, const task::TaskSpec& spec, const std::vector<bool>& labelled,
                            LabelCursor& labels, std::ostream& out);
/// The same with the labels of an inference in memory.
void writeLabelledRecording(const std::string& path, const task::TaskSpec& spec, const Inference& inference,
                            std::ostream& out);

}  // namespace ddace::label
