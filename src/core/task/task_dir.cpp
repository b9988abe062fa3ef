#include "ddace/task/task_dir.h"
#include "ddace/task/summary.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <set>

namespace fs = std::filesystem;

namespace ddace::task {

std::vector<std::string> TaskDir::vocabulary() const {
  if (spec.actions_declared) return spec.actions;
  std::set<std::string> seen;
  for (const auto& d : demos)
    for (const auto& row : d.labels)
      for (const auto& l : row)
        if (!l.isNull()) seen.insert(l.action);
  return {seen.begin(), seen.end()};
}

namespace {

struct DemoListing {
  std::vector<fs::path> csvs, partial;  ///< each sorted by file name
};

/// The entries of demos/ by name (nothing is opened: the readers refuse what is not a
/// regular file, by name). Throws ddace::Error naming the directory when it cannot be read.
DemoListing listDemos(const fs::path& demos) {
  DemoListing out;
  std::error_code ec;
  fs::directory_iterator it(demos, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const fs::path& p = it->path();
    if (p.extension() == ".csv") out.csvs.push_back(p);
    else if (p.extension() == ".partial") out.partial.push_back(p);
  }
  if (ec) throw Error(Diagnostic{demos.string(), 0, 0, "cannot read the directory: " + ec.message()});
  std::sort(out.csvs.begin(), out.csvs.end());
  std::sort(out.partial.begin(), out.partial.end());
  return out;
}

/// What `path` is, following symlinks; a symlink loop or an unreadable parent is an error.
fs::file_status statusOf(const fs::path& path, std::string& error) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && st.type() != fs::file_type::not_found) error = "cannot read: " + ec.message();
  return st;
}

}  // namespace

std::vector<std::string> demoFiles(const std::string& task_dir) {
  const fs::path demos = fs::path(task_dir) / "demos";
  std::string error;
  const fs::file_status st = statusOf(demos, error);
  if (!error.empty()) throw Error(Diagnostic{demos.string(), 0, 0, error});
  if (!fs::is_directory(st))
    throw Error(Diagnostic{demos.string(), 0, 0, "no demos/ directory (expected demos/*.csv)"});
  std::vector<std::string> files;
  for (const auto& p : listDemos(demos).csvs) files.push_back(p.string());
  return files;
}

std::string demoFile(const std::string& task_dir, long index, const std::string& what) {
  const std::vector<std::string> files = demoFiles(task_dir);
  if (index < 0 || index >= static_cast<long>(files.size()))
    throw Error(what + " = " + std::to_string(index) + ", but " + (fs::path(task_dir) / "demos").string() + " has " +
                std::to_string(files.size()) + " demonstrations" +
                (files.empty() ? "" : " (0.." + std::to_string(files.size() - 1) + ")"));
  return files[static_cast<size_t>(index)];
}

namespace {

/// The checks of a task directory, every error into `errors`; `read` takes each
/// demonstration CSV and throws ddace::Error for one with errors.
template <class Read>
void checkDir(const std::string& path, TaskSpec& spec, std::vector<Diagnostic>& errors, Read read) {
  std::string error;
  if (!fs::is_directory(statusOf(path, error))) {
    errors.push_back({path, 0, 0, error.empty() ? "not a task directory (expected task.yaml and demos/*.csv)" : error});
    return;
  }
  const std::string yaml = (fs::path(path) / "task.yaml").string();
  if (statusOf(yaml, error).type() == fs::file_type::not_found && error.empty()) {
    errors.push_back({yaml, 0, 0, "missing task.yaml"});
    return;
  }
  try {
    spec = readTaskYaml(yaml);
  } catch (const Error& e) {
    errors.insert(errors.end(), e.diagnostics().begin(), e.diagnostics().end());
    return;  // demonstrations cannot be checked without the scene
  }

  const fs::path demos = fs::path(path) / "demos";
  DemoListing listing;
  const fs::file_status demos_status = statusOf(demos, error);
  if (!error.empty()) {
    errors.push_back({demos.string(), 0, 0, error});
    return;
  }
  if (fs::is_directory(demos_status)) {
    try {
      listing = listDemos(demos);
    } catch (const Error& e) {
      errors.insert(errors.end(), e.diagnostics().begin(), e.diagnostics().end());
      return;
    }
  }
  if (listing.csvs.empty() && listing.partial.empty())
    errors.push_back({demos.string(), 0, 0, "no demonstrations (expected demos/*.csv)"});
  for (const auto& p : listing.partial) {
    errors.push_back({p.string(), 0, 0,
                      "partial recording (the recorder stopped without finishing it): `ddace recover " +
                          p.parent_path().parent_path().string() +
                          "` keeps its whole rows as .csv (cutting a row torn by the kill), or delete it"});
  }
  for (const auto& p : listing.csvs) {
    try {
      read(p.string());
    } catch (const Error& e) {
      errors.insert(errors.end(), e.diagnostics().begin(), e.diagnostics().end());
    }
  }
}

}  // namespace

namespace {

/// Step grouping across the demonstrations (rule 6 of "Step grouping"): the runs of steps
/// to merge in each of `demos`.
template <class Demo>
std::vector<std::vector<StepRun>> runsShownAsOne(const std::vector<Demo>& demos, const TaskSpec& spec) {
  std::vector<std::vector<Step>> steps_of;
  for (const Demo& d : demos) steps_of.push_back(d.steps);
  return stepsShownAsOne(steps_of, spec);
}

}  // namespace

void groupStepsAcrossDemonstrations(TaskDir& dir) {
  const auto runs = runsShownAsOne(dir.demos, dir.spec);
  for (size_t d = 0; d < dir.demos.size(); ++d) dir.demos[d].mergeSteps(runs[d]);
}

TaskDirReport checkTaskDir(const std::string& path) {
  TaskDirReport report;
  report.dir.path = path;
  checkDir(path, report.dir.spec, report.errors,
           [&](const std::string& csv) { report.dir.demos.push_back(readDemonstrationCsv(csv, report.dir.spec)); });
  groupStepsAcrossDemonstrations(report.dir);
  return report;
}

TaskDirSummary summarizeTaskDir(const std::string& path) {
  TaskDirSummary summary;
  summary.path = path;
  checkDir(path, summary.spec, summary.errors,
           [&](const std::string& csv) { summary.demos.push_back(summarizeDemonstrationCsv(csv, summary.spec)); });
  const auto runs = runsShownAsOne(summary.demos, summary.spec);
  for (size_t d = 0; d < summary.demos.size(); ++d) {
    DemonstrationSummary& s = summary.demos[d];
    if (runs[d].empty()) continue;
    std::vector<double> keyframe_t;
    for (size_t k = 0, r = 0; k < s.steps.size(); ++k) {
      if (!(r < runs[d].size() && k > runs[d][r].first && k <= runs[d][r].last)) keyframe_t.push_back(s.keyframe_t[k]);
      if (r < runs[d].size() && k == runs[d][r].last) ++r;
    }
    s.steps = mergedSteps(s.steps, runs[d]);
    s.keyframe_t = std::move(keyframe_t);
    s.step_count = s.steps.size();
  }
  return summary;
}

std::vector<std::string> TaskDirSummary::vocabulary() const {
  if (spec.actions_declared) return spec.actions;
  std::set<std::string> seen;
  for (const auto& d : demos)
    for (const auto& step : d.steps)
      for (const auto& token : step.tokens) seen.insert(token.action);
  return {seen.begin(), seen.end()};
}

TaskDir loadTaskDir(const std::string& path) {
  TaskDirReport report = checkTaskDir(path);
  if (!report.errors.empty()) throw Error(report.errors);
  return std::move(report.dir);
}

std::vector<OwnedFile> taskDirFiles(const TaskDir& dir, const std::string& prefix) {
  std::vector<OwnedFile> files;
  files.emplace_back(prefix + "task.yaml", taskYamlText(dir.spec));
  char name[32];
  for (size_t i = 0; i < dir.demos.size(); ++i) {
    std::snprintf(name, sizeof name, "demo_%03zu.csv", i);
    files.emplace_back(prefix + "demos/" + name, demonstrationCsvText(dir.demos[i], dir.spec));
  }
  return files;
}

void writeTaskDir(const TaskDir& dir, const std::string& path) {
  writeOwnedDirectory(path, taskDirFiles(dir), "ddace", true);
}

}  // namespace ddace::task
