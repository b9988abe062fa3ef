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
  size_t segments = 0;
  int end_row = 0;  ///< the END snapshot's row (the last row)
};

/// Reads one CSV as readDemonstrationCsv does (same checks, same errors) and keeps only
/// what it derives.
DemonstrationSummary summarizeDemonstrationCsv(const std::string& path, const TaskSpec& spec);

/// mergedOnsetNotes() of the steps of `source`.
std::vector<Diagnostic> mergedOnsetNotes(const std::string& source, const std::vector<Step>& steps,
                                         const TaskSpec& spec);

/// checkTaskDir without keeping the rows: the same checks and errors, a summary per
/// valid demonstration.
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
