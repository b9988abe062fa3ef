// A task directory: task.yaml + demos/*.csv (read in file-name order).
#pragma once

#include <string>
#include <vector>

#include "ddace/task/demonstration.h"
#include "ddace/task/owned_dir.h"
#include "ddace/task/task_spec.h"

namespace ddace::task {

struct TaskDir {
  std::string path;
  TaskSpec spec;
  std::vector<Demonstration> demos;

  /// The action vocabulary: task.yaml's `actions`, else every action seen in the
  /// demonstrations, sorted.
  std::vector<std::string> vocabulary() const;
};

/// Everything found while reading a task directory; `errors` empty means valid.
struct TaskDirReport {
  TaskDir dir;  ///< demonstrations with errors are left out
  std::vector<Diagnostic> errors;
};

/// The demonstration CSVs of a task directory (`<task_dir>/demos/*.csv`), in file-name
/// order: the order in which every reader takes them. Throws ddace::Error naming the
/// directory when demos/ is missing or cannot be read.
std::vector<std::string> demoFiles(const std::string& task_dir);
/// The path of the `index`-th (0-based) demonstration CSV of demoFiles(task_dir). Throws
/// ddace::Error "<what> = <index>, but <task_dir>/demos has <n> demonstrations (0..n-1)"
/// when there is no such demonstration; `what` names where the index came from (e.g.
/// "parameter '/sequence/replay_demo'").
std::string demoFile(const std::string& task_dir, long index, const std::string& what = "demonstration index");

/// Step grouping across the demonstrations of `dir` (docs/task-format.md, "Step grouping",
/// rule 6): merges the runs of steps stepsShownAsOne finds (Demonstration::mergeSteps).
/// The readers below apply it; a caller that builds demonstrations itself applies it once
/// they are all there.
void groupStepsAcrossDemonstrations(TaskDir& dir);
/// Reads everything that can be read and collects every error (for `ddace validate`); the
/// demonstrations' steps grouped across them (groupStepsAcrossDemonstrations).
TaskDirReport checkTaskDir(const std::string& path);
/// Reads a task directory; throws ddace::Error listing every error. Nothing is
/// returned (so nothing is trained) when any file has an error.
TaskDir loadTaskDir(const std::string& path);
/// The files of `dir` as a task directory: task.yaml and demos/demo_000.csv,
/// demos/demo_001.csv, ..., each path prefixed with `prefix` (e.g. "train/").
std::vector<OwnedFile> taskDirFiles(const TaskDir& dir, const std::string& prefix = "");
/// Writes `dir` as the whole content of the directory `path` (owned_dir.h): a directory
/// holding anything it did not write is refused, naming what is there; its own earlier
/// output is replaced in one step, so no old demonstration survives.
void writeTaskDir(const TaskDir& dir, const std::string& path);

}  // namespace ddace::task
