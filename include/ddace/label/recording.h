// Labelling a recording as a stream (`ddace label`): memory independent of its length.
// Pass 1 feeds its rows to a Labeller; pass 2 copies the file with the inferred labels.
// The file is checked first with the task module's own reader (task/summary.h), so these
// passes see only a valid ddace-task/1 CSV; a file that changed in between is an error.
#pragma once

#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/label/label.h"

namespace ddace::label {

/// Calls `row(line, t, positions)` for every data row of the CSV at `path` (a file that
/// task::summarizeDemonstrationCsv accepted), reading it as a stream. Throws ddace::Error
/// "path:line: ..." when a row does not read (the file changed since it was checked).
void forEachRow(const std::string& path, const task::TaskSpec& spec,
                const std::function<void(int line, double t, const std::vector<Eigen::Vector2d>& positions)>& row);

/// The inference of one recording, streamed (pass 1).
Inference inferRecording(const std::string& path, const task::TaskSpec& spec, const Example* example);

/// Writes the CSV at `path` with `inference`'s labels to `out` (pass 2): t and positions
/// as the file holds them (same digits), label columns for every entity with a token,
/// none of the file's own (empty) label columns.
void writeLabelledRecording(const std::string& path, const task::TaskSpec& spec, const Inference& inference,
                            std::ostream& out);

}  // namespace ddace::label
