// Recording demonstrations as ddace-task/1 (docs/task-format.md): a task directory
// with task.yaml and one demos/demo_NNN.csv per demonstration.
//
// Crash safety: rows go to demos/demo_NNN.csv.partial, each row (the first one with
// the header) built in the recorder's own buffer and handed to the kernel in one
// write(2), never through stdio, so every row whose addRow() returned is in the file,
// whenever the process dies; fdatasync at least every `flush_period_s` bounds what a
// power loss takes. stop() checks the file with the task module's reader and renames it
// to demo_NNN.csv. A recorder that is killed leaves the .partial file: whole rows, and
// at most a torn last row without its newline (Linux may end a write(2) to a file at a
// page boundary when SIGKILL arrives during it); empty when it died before the first
// row. `ddace validate` reports it as a partial recording; recoverPartialRecording()
// (`ddace recover`) keeps its whole rows as the .csv.
//
// Owns: task.yaml from the configuration, the CSV rows, the current labels.
// Must not: know about ROS or the tracker (recorder_node feeds it).
// Units: seconds (any monotonic clock; the CSV's t starts at 0), metres, table frame.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/label/label.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/tracker.h"

namespace ddace::vision {

/// config/recorder.yaml.
struct RecorderConfig {
  std::string output_dir;  ///< the task directory (created); "~/" is expanded
  /// Infer the labels from the motion when a demonstration without any label is stopped
  /// (docs/labels.md): people only demonstrate. Labels set during the recording win.
  bool infer_labels = true;
  std::string example;          ///< a demonstration labelled by hand for the action words ("" for none)
  double rate_hz = 30.0;        ///< rows per second
  double flush_period_s = 1.0;  ///< rows reach the disk at least this often
  task::TaskSpec spec;          ///< entities from markers.yaml, the rest from `task:`
};

/// Parses recorder.yaml; entities (order, names, kinds, types) come from `markers`.
/// Throws ddace::Error with file:line:column.
RecorderConfig parseRecorderConfig(const std::string& text, const std::string& file, const MarkerConfig& markers);
RecorderConfig loadRecorderConfig(const std::string& path, const MarkerConfig& markers);

/// The latest measured position of each entity of a task, from the tracker's reports:
/// what a recorded row holds. An entity never measured has no position (not (0, 0)),
/// so no row can be written before every entity was seen once. It also tells whether the
/// scene is at rest (a demonstration starts from one: its first row is every entity's
/// start) and which entities were hidden in how many rows.
class LatestPositions {
 public:
  /// "At rest" is the label inference's (label::SegmentationOptions::forTask: positions
  /// within still_m for still_s), so that the first row is a rest for the inference too.
  explicit LatestPositions(const task::TaskSpec& spec);
  /// A tracker report for `name` at time `t` (seconds, any monotonic clock); `measured`
  /// false (never seen yet) and names outside the task are ignored. `stale`: the tracker
  /// holds the pose without seeing it.
  void update(const std::string& name, const Eigen::Vector2d& position_m, bool stale, bool measured, double t);
  /// Every entity's position in task order once all were measured, else nullopt.
  std::optional<std::vector<Eigen::Vector2d>> all() const;
  /// The entities never measured, comma-separated in task order ("" when none).
  std::string missing() const;
  /// The entities that moved within still_s before `t` (comma-separated in task order; ""
  /// when none did). appeared(t) lists those seen for less than still_s: the scene is at
  /// rest when both are "".
  std::string moving(double t) const;
  /// The entities first measured within still_s before `t`: not yet known to be at rest
  /// (a tracker just started, a marker just uncovered), comma-separated in task order.
  std::string appeared(double t) const;
  /// Seconds the scene must be at rest before a demonstration starts.
  double stillSeconds() const { return still_s_; }
  /// How many entities' latest positions are stale.
  int stale() const;
  /// A row was written: every entity stale now counts it. resetRows() starts a new count.
  void countRow();
  void resetRows();
  /// The entities hidden in some rows since resetRows(), each with the count and whether
  /// the user has to act: "" when none was. A goal (does not move) or an entity that
  /// reappeared where it was hidden is harmless; one that reappeared elsewhere moved
  /// unseen (a jump in its path).
  std::string staleRowsReport() const;

 private:
  std::vector<std::string> names_;  // task order
  std::vector<task::EntityKind> kinds_;
  std::vector<std::optional<Eigen::Vector2d>> positions_;
  std::vector<bool> stale_;
  std::vector<Eigen::Vector2d> rest_;  // where each entity rests (or last started to move)
  std::vector<double> rest_since_;     // since when
  std::vector<double> first_seen_;
  std::vector<long> stale_rows_;
  std::vector<bool> moved_hidden_;  // reappeared farther than start_m from where it was hidden
  double still_m_ = 0, still_s_ = 0, start_m_ = 0;
};

/// What recoverPartialRecording() kept and cut.
struct RecoveredRecording {
  std::string csv_path;  ///< the demonstration it wrote: the .partial name without ".partial"
  size_t rows = 0;       ///< whole rows kept
  size_t steps = 0;      ///< labelled steps in them (0: unlabelled, `ddace label` infers them)
  std::string torn_row;  ///< the torn last row it cut (bytes after the last newline), "" when none
};

/// Keeps every whole row of a recorder's `partial_path` (demos/NAME.csv.partial) as
/// demos/NAME.csv: the bytes up to its last newline, so only a torn last row (no newline:
/// the recorder died while writing it) is cut, and returned. The rows kept are read back
/// with the task module's reader (any length) before the .partial file is deleted. Throws
/// ddace::Error naming the .partial file (line:column of a bad row) and leaves it as it
/// was, with no .csv written, when NAME.csv exists, the file has no whole row after its
/// header, or a row kept does not read as `spec`'s demonstration.
RecoveredRecording recoverPartialRecording(const std::string& partial_path, const task::TaskSpec& spec);

class DemoRecorder {
 public:
  /// Creates `task_dir`/demos and writes task.yaml, or checks that an existing
  /// task.yaml describes the same task. Throws ddace::Error naming the directory.
  DemoRecorder(task::TaskSpec spec, std::string task_dir, double flush_period_s = 1.0);
  ~DemoRecorder();
  DemoRecorder(const DemoRecorder&) = delete;
  DemoRecorder& operator=(const DemoRecorder&) = delete;

  /// Starts demo_NNN (the next free number) at time `t0`: creates the .partial file
  /// (its header goes out with the first row), every label null. Returns the final
  /// .csv path. Throws when already recording or the file cannot be created.
  std::string start(double t0);
  /// Sets the label of `entity` from now on. action "" or "idle" = none; target ""
  /// = none. Throws ddace::Error (and changes nothing) when the entity is unknown or
  /// has no label columns (a goal), the action is not in the task's vocabulary, a
  /// target is given without action, or the target is unknown or the entity itself.
  void setLabel(const std::string& entity, const std::string& action, const std::string& target);
  /// Every entity's label back to none.
  void clearLabels();
  /// Appends a row at time `t` with the positions of every entity (task order): one
  /// write(2) of the whole row. Rows whose t is not after the previous row's are
  /// dropped (returns false). Throws ddace::Error naming the file when the write fails.
  bool addRow(double t, const std::vector<Eigen::Vector2d>& positions);
  /// Flushes, re-reads the file with the task module (errors keep it .partial and
  /// throw), renames it to .csv and returns that path. With inferLabels() set and no
  /// label recorded, the .csv is the recording with labels inferred from its motion
  /// (streamed: any length), and inferenceNotes() lists what the person should check.
  std::string stop();
  /// Labels inferred on stop() (nullopt: never); the example names the action words.
  void inferLabels(bool on, std::optional<label::Example> example = std::nullopt);
  /// The inferred steps of the last stop(), as "[R1:move:G1 R2:move:G2] [...]" ("" when not
  /// inferred, "none" when no step was found).
  const std::string& inferredSteps() const { return inferred_steps_; }
  /// What the last stop() could not infer surely, "demos/demo_003.csv:47: ..." each.
  const std::vector<std::string>& inferenceNotes() const { return notes_; }
  /// What the person does about inferenceNotes(), one line each ("" when there are none):
  /// nothing when the labels taken are what was demonstrated, else how to correct them; or,
  /// when no step was found, to delete the recording and demonstrate again.
  const std::string& inferenceAdvice() const { return advice_; }
  /// Stops and deletes the current recording.
  void discard();
  /// Forces the rows written so far to the disk now (fdatasync).
  void flush();

  bool recording() const { return fd_ >= 0; }
  size_t rows() const { return rows_; }
  /// Seconds since start() of the last row.
  double duration() const { return last_t_; }
  const std::string& partialPath() const { return partial_path_; }
  const task::TaskSpec& spec() const { return spec_; }
  /// Current label of entity i.
  const task::Label& label(size_t i) const { return labels_[i]; }
  /// Label columns are written for robots and objects, not for goals.
  bool hasLabelColumns(size_t i) const { return spec_.entities[i].kind != task::EntityKind::Goal; }

 private:
  /// inferenceAdvice() for the notes of `inf` on the demonstration saved as `path`.
  std::string reviewAdvice(const label::Inference& inf, const std::string& path) const;
  task::TaskSpec spec_;
  std::string dir_;
  double flush_period_s_;
  void writeWhole(const std::string& bytes);
  void closeFile();

  bool infer_ = false;
  std::optional<label::Example> example_;
  std::string inferred_steps_;
  std::vector<std::string> notes_;
  std::string advice_;
  bool labelled_ = false;  ///< a label was set during this recording

  int fd_ = -1;
  std::string header_;  // written with the first row
  std::string partial_path_, final_path_;
  std::vector<task::Label> labels_;
  double t0_ = 0, last_t_ = -1, last_flush_ = 0;
  size_t rows_ = 0;
};

}  // namespace ddace::vision
