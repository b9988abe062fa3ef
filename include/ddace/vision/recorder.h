// Recording demonstrations as ddace-task/1 (shared/spec/task-format.md): a task
// directory with task.yaml and one demos/demo_NNN.csv per demonstration.
//
// Crash safety: rows go to demos/demo_NNN.csv.partial, flushed (and fdatasync'ed) at
// least every `flush_period_s`; stop() checks the file with the task module's reader
// and renames it to demo_NNN.csv. A recorder that is killed leaves the .partial
// file, which holds whole rows only and is readable as a CSV; `ddace validate`
// reports it as a partial recording (rename it to .csv to use it, or delete it).
//
// Owns: task.yaml from the configuration, the CSV rows, the current labels.
// Must not: know about ROS or the tracker (recorder_node feeds it).
// Units: seconds (any monotonic clock; the CSV's t starts at 0), metres, table frame.
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/tracker.h"

namespace ddace::vision {

/// config/recorder.yaml.
struct RecorderConfig {
  std::string output_dir;        ///< the task directory (created); "~/" is expanded
  double rate_hz = 30.0;         ///< rows per second
  double flush_period_s = 1.0;   ///< rows reach the disk at least this often
  task::TaskSpec spec;           ///< entities from markers.yaml, the rest from `task:`
};

/// Parses recorder.yaml; entities (order, names, kinds, types) come from `markers`.
/// Throws ddace::Error with file:line:column.
RecorderConfig parseRecorderConfig(const std::string& text, const std::string& file, const MarkerConfig& markers);
RecorderConfig loadRecorderConfig(const std::string& path, const MarkerConfig& markers);

class DemoRecorder {
 public:
  /// Creates `task_dir`/demos and writes task.yaml, or checks that an existing
  /// task.yaml describes the same task. Throws ddace::Error naming the directory.
  DemoRecorder(task::TaskSpec spec, std::string task_dir, double flush_period_s = 1.0);
  ~DemoRecorder();
  DemoRecorder(const DemoRecorder&) = delete;
  DemoRecorder& operator=(const DemoRecorder&) = delete;

  /// Starts demo_NNN (the next free number) at time `t0`: writes the header of the
  /// .partial file, every label null. Returns the final .csv path. Throws when already
  /// recording or the file cannot be created.
  std::string start(double t0);
  /// Sets the label of `entity` from now on. action "" or "idle" = none; target ""
  /// = none. Throws ddace::Error (and changes nothing) when the entity is unknown or
  /// has no label columns (a goal), the action is not in the task's vocabulary, a
  /// target is given without action, or the target is unknown or the entity itself.
  void setLabel(const std::string& entity, const std::string& action, const std::string& target);
  /// Every entity's label back to none.
  void clearLabels();
  /// Appends a row at time `t` with the positions of every entity (task order).
  /// Rows whose t is not after the previous row's are dropped (returns false).
  bool addRow(double t, const std::vector<Eigen::Vector2d>& positions);
  /// Flushes, re-reads the file with the task module (errors keep it .partial and
  /// throw), renames it to .csv and returns that path.
  std::string stop();
  /// Stops and deletes the current recording.
  void discard();
  /// Writes buffered rows to the disk now.
  void flush();

  bool recording() const { return file_ != nullptr; }
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
  task::TaskSpec spec_;
  std::string dir_;
  double flush_period_s_;
  std::FILE* file_ = nullptr;
  std::string partial_path_, final_path_;
  std::vector<task::Label> labels_;
  double t0_ = 0, last_t_ = -1, last_flush_ = 0;
  size_t rows_ = 0;
};

}  // namespace ddace::vision
