// Summaries of demonstrations and task directories computed while they are read, keeping
// none of their rows: memory independent of a file's length (`ddace validate`). The
// same checks and errors as readDemonstrationCsv / checkTaskDir, the same steps.
#pragma once

#include <string>
#include <vector>

#include "ddace/task/task_dir.h"

namespace ddace::task {

/// What a demonstration derives, without its rows.
struct DemonstrationSummary {
  std::string source;
  size_t rows = 0;
  double t_first = 0, t_last = 0;  ///< seconds
  std::vector<Step> steps;         ///< exactly Demonstration::steps of the same file
  std::vector<double> keyframe_t;  ///< [step] t at its keyframe, seconds
  size_t step_count = 0;           ///< steps.size(), or all of them when only the last is kept
  size_t segments = 0;
  int end_row = 0;  ///< the END snapshot's row (the last row)
};

/// Reads one CSV as readDemonstrationCsv does (same checks, same errors) and keeps only
/// what it derives, of a file of any size. `keep_steps` false: `steps` holds the last
/// step only and keyframe_t none (step_count and segments count them all), so memory
/// does not grow with the steps either (`ddace label`'s read-back check).
DemonstrationSummary summarizeDemonstrationCsv(const std::string& path, const TaskSpec& spec, bool keep_steps = true);

/// stepGroupingNotes() of the steps of `source`.
std::vector<Diagnostic> stepGroupingNotes(const std::string& source, const std::vector<Step>& steps,
                                          const TaskSpec& spec);

/// checkTaskDir without keeping the rows: the same checks and errors, a summary per
/// valid demonstration, its steps grouped across the demonstrations as checkTaskDir's.
struct TaskDirSummary {
  std::string path;
  TaskSpec spec;
  std::vector<DemonstrationSummary> demos;  ///< demonstrations with errors are left out
  std::vector<Diagnostic> errors;
  /// As TaskDir::vocabulary(): declared actions, else every action of a token.
  std::vector<std::string> vocabulary() const;
};
TaskDirSummary summarizeTaskDir(const std::string& path);

}  // namespace ddace::task
