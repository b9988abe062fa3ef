// ddace recover: keep the whole rows of the recordings a killed recorder left (.csv.partial).
#include <algorithm>
#include <filesystem>
#include <iostream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/recorder.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

bool isPartial(const fs::path& p) {
  const std::string name = p.filename().string();
  const std::string suffix = ".csv.partial";
  return name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// The .csv.partial files `arg` names: itself, or those in the task directory's demos/, sorted.
std::vector<fs::path> partialFiles(const fs::path& arg) {
  std::error_code ec;
  if (!fs::is_directory(arg, ec)) {
    if (!fs::exists(arg, ec)) throw Error(Diagnostic{arg.string(), 0, 0, "does not exist"});
    if (!isPartial(arg))
      throw Error(Diagnostic{arg.string(), 0, 0, "not a recorder's partial recording (demos/NAME.csv.partial)"});
    return {arg};
  }
  std::vector<fs::path> files;
  for (fs::directory_iterator it(arg / "demos", ec), end; !ec && it != end; it.increment(ec))
    if (isPartial(it->path())) files.push_back(it->path());
  if (ec) throw Error(Diagnostic{(arg / "demos").string(), 0, 0, "cannot list: " + ec.message()});
  std::sort(files.begin(), files.end());
  return files;
}

/// Recovers one file, prints what was kept and cut; false (and its errors) when it is left as it was.
bool recoverOne(const fs::path& partial) {
  const fs::path task_dir = partial.parent_path().parent_path();
  try {
    const task::TaskSpec spec = task::readTaskYaml((task_dir / "task.yaml").string());
    const vision::RecoveredRecording r = vision::recoverPartialRecording(partial.string(), spec);
    std::cout << partial.string() << " -> " << r.csv_path << ": " << r.rows << " rows kept, labelled steps: " << r.steps
              << "\n";
    if (!r.torn_row.empty())
      std::cout << "  cut its torn last row (" << r.torn_row.size()
                << " bytes without a newline: the recorder died while writing it): " << r.torn_row << "\n";
    if (r.steps == 0)
      std::cout << "  unlabelled (labels are inferred when a recording is stopped, and this one was not): "
                << unlabelledAdvice(task_dir.string(), false) << "\n";
    return true;
  } catch (const Error& e) {
    std::cerr << e.what() << "\n" << partial.string() << ": left as it was (no .csv written)\n";
    return false;
  }
}

int runRecover(const std::vector<std::string>& argv) {
  Args args(argv, {});
  if (args.positional().empty()) throw Error("missing argument DIR or FILE (a task directory or a .csv.partial file)");
  bool ok = true;
  for (const auto& arg : args.positional()) {
    const std::vector<fs::path> files = partialFiles(arg);
    if (files.empty()) std::cout << arg << ": no partial recording (demos/*.csv.partial): nothing to recover\n";
    for (const auto& f : files) ok = recoverOne(f) && ok;
  }
  return ok ? 0 : 1;
}

DDACE_COMMAND({"recover", "ddace recover DIR|FILE.csv.partial...",
               "keep the whole rows of a killed recorder's demos/*.csv.partial files as .csv (a torn last "
               "row is cut and shown)",
               runRecover});

}  // namespace
}  // namespace ddace::cli
