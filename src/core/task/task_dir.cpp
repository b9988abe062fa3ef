#include "ddace/task/task_dir.h"

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

TaskDirReport checkTaskDir(const std::string& path) {
  TaskDirReport report;
  report.dir.path = path;
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    report.errors.push_back({path, 0, 0, "not a task directory (expected task.yaml and demos/*.csv)"});
    return report;
  }
  const std::string yaml = (fs::path(path) / "task.yaml").string();
  if (!fs::exists(yaml, ec)) {
    report.errors.push_back({yaml, 0, 0, "missing task.yaml"});
    return report;
  }
  try {
    report.dir.spec = readTaskYaml(yaml);
  } catch (const Error& e) {
    report.errors.insert(report.errors.end(), e.diagnostics().begin(), e.diagnostics().end());
    return report;  // demonstrations cannot be checked without the scene
  }

  const fs::path demos = fs::path(path) / "demos";
  std::vector<fs::path> csvs, partial;
  if (fs::is_directory(demos, ec)) {
    for (const auto& entry : fs::directory_iterator(demos, ec)) {
      if (!entry.is_regular_file()) continue;
      const std::string name = entry.path().filename().string();
      if (entry.path().extension() == ".csv") csvs.push_back(entry.path());
      else if (entry.path().extension() == ".partial") partial.push_back(entry.path());
    }
  }
  std::sort(csvs.begin(), csvs.end());
  std::sort(partial.begin(), partial.end());
  if (csvs.empty() && partial.empty())
    report.errors.push_back({demos.string(), 0, 0, "no demonstrations (expected demos/*.csv)"});
  for (const auto& p : partial) {
    report.errors.push_back({p.string(), 0, 0,
                             "partial recording (the recorder stopped without finishing it): "
                             "inspect it, then rename it to .csv to use it or delete it"});
  }
  for (const auto& p : csvs) {
    try {
      report.dir.demos.push_back(readDemonstrationCsv(p.string(), report.dir.spec));
    } catch (const Error& e) {
      report.errors.insert(report.errors.end(), e.diagnostics().begin(), e.diagnostics().end());
    }
  }
  return report;
}

TaskDir loadTaskDir(const std::string& path) {
  TaskDirReport report = checkTaskDir(path);
  if (!report.errors.empty()) throw Error(report.errors);
  return std::move(report.dir);
}

void writeTaskDir(const TaskDir& dir, const std::string& path) {
  std::error_code ec;
  const fs::path demos = fs::path(path) / "demos";
  fs::create_directories(demos, ec);
  if (ec) throw Error(Diagnostic{demos.string(), 0, 0, "cannot create directory: " + ec.message()});
  // Old demonstrations would silently join the new ones: remove them.
  for (const auto& entry : fs::directory_iterator(demos, ec))
    if (entry.path().extension() == ".csv") fs::remove(entry.path(), ec);
  writeTaskYaml(dir.spec, (fs::path(path) / "task.yaml").string());
  char name[32];
  for (size_t i = 0; i < dir.demos.size(); ++i) {
    std::snprintf(name, sizeof name, "demo_%03zu.csv", i);
    writeDemonstrationCsv(dir.demos[i], dir.spec, (demos / name).string());
  }
}

}  // namespace ddace::task
