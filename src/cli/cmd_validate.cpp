// ddace validate: check a task directory and summarise what the spec derives from it.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/task/summary.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

std::string stepText(const task::Step& step, const task::TaskSpec& spec) {
  std::string s = "[";
  for (size_t i = 0; i < step.tokens.size(); ++i) s += (i ? " " : "") + task::tokenKey(step.tokens[i], spec);
  return s + "]";
}

/// True when `path`/demos holds no recording at all (`ddace init` made it, nothing recorded yet).
bool nothingRecorded(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(fs::path(path) / "task.yaml", ec)) return false;
  for (fs::directory_iterator it(fs::path(path) / "demos", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() >= 4 && (name.compare(name.size() - 4, 4, ".csv") == 0 || name.find(".csv.") != std::string::npos))
      return false;
  }
  return !ec;
}

/// Validates one task directory; prints its summary or its errors. Returns true when valid.
/// Demonstrations are summarised while they are read (no rows kept): any length validates.
/// A new task with nothing recorded yet validates its task.yaml and says so.
bool validateOne(const std::string& path, bool verbose) {
  if (nothingRecorded(path)) {
    task::TaskSpec spec;
    try {
      spec = task::readTaskYaml((fs::path(path) / "task.yaml").string());
    } catch (const Error& e) {
      std::cerr << path << ": " << e.diagnostics().size() << " error(s)\n" << e.what() << "\n";
      return false;
    }
    std::cout << path << ": task '" << spec.name << "', " << spec.entities.size() << " entities (";
    for (size_t i = 0; i < spec.entities.size(); ++i)
      std::cout << (i ? ", " : "") << spec.entities[i].name << " " << task::toString(spec.entities[i].kind);
    std::cout << "), " << spec.goal_conditions.size()
              << " goal conditions, no demonstrations yet (record some: README, \"Your own task\")\n";
    return true;
  }
  const task::TaskDirSummary dir = task::summarizeTaskDir(path);
  if (!dir.errors.empty()) {
    std::cerr << path << ": " << dir.errors.size() << " error(s)\n";
    for (const auto& d : dir.errors) std::cerr << d.str() << "\n";
    return false;
  }
  const auto& spec = dir.spec;
  std::cout << path << ": task '" << spec.name << "', " << spec.entities.size() << " entities (";
  for (size_t i = 0; i < spec.entities.size(); ++i)
    std::cout << (i ? ", " : "") << spec.entities[i].name << " " << task::toString(spec.entities[i].kind);
  std::cout << "), actions [";
  const auto vocab = dir.vocabulary();
  for (size_t i = 0; i < vocab.size(); ++i) std::cout << (i ? ", " : "") << vocab[i];
  std::cout << "], " << dir.demos.size() << " demonstrations\n";

  std::vector<std::vector<task::Step>> steps_of;
  for (const auto& d : dir.demos) {
    steps_of.push_back(d.steps);
    std::printf("  %s: %zu rows (%.2f s), %zu keyframes, %zu steps, %zu segments\n",
                fs::path(d.source).filename().c_str(), d.rows, d.t_last - d.t_first, d.steps.size(), d.steps.size(),
                d.segments);
    // Where step grouping merged a late label into its step (people label one robot after
    // another), or a step began while the step before still ran.
    for (const auto& note : task::stepGroupingNotes(d.source, d.steps, spec))
      std::printf("    %s\n", note.str().c_str());
    if (verbose || d.steps.empty()) {
      for (size_t k = 0; k < d.steps.size(); ++k)
        std::printf("    step %zu @ row %d (t = %.2f s): %s\n", k + 1, d.steps[k].keyframe_row, d.keyframe_t[k],
                    stepText(d.steps[k], spec).c_str());
      std::printf("    END @ row %d\n", d.end_row);
    }
  }
  const auto unlabelled =
      std::count_if(dir.demos.begin(), dir.demos.end(), [](const auto& d) { return d.steps.empty(); });
  if (unlabelled > 0)
    std::cout
        << "  " << unlabelled << " of " << dir.demos.size()
        << " demonstrations have no labelled step (recorded with infer_labels: false), which ddace train refuses: "
        << unlabelledAdvice(path, static_cast<size_t>(unlabelled) == dir.demos.size()) << "\n";
  const task::CommonSteps common = task::commonSteps(steps_of);
  // A labelling slip (one token unlike every other demonstration's) is reported even with
  // --verbose: training takes the steps as fixed all the same (docs/tgn.md, "Fixed order").
  if (common.fixed && !common.slips.empty()) {
    std::cout << "  every demonstration has the same " << common.steps.size() << " steps but for "
              << common.slips.size() << " labelling slip" << (common.slips.size() == 1 ? "" : "s") << ":\n";
    for (const auto& slip : common.slips)
      std::cout << "    " << fs::path(dir.demos[slip.demo].source).filename().string() << ": step " << slip.step + 1
                << ": " << task::tokenKey(slip.token, spec) << " where the others have "
                << task::tokenKey(slip.expected, spec) << "\n";
  }
  const bool same = common.fixed && common.slips.empty();
  if (!dir.demos.empty() && common.fixed && !verbose) {
    if (same) std::cout << "  every demonstration has the same " << common.steps.size() << " steps:\n";
    for (size_t k = 0; k < common.steps.size(); ++k)
      std::cout << "    step " << k + 1 << ": " << stepText(common.steps[k], spec) << "\n";
    std::cout << "    then END\n";
  } else if (!dir.demos.empty() && !common.fixed && !verbose) {
    std::cout << "  the demonstrations differ in their steps (--verbose lists them)\n";
  }
  return true;
}

int runValidate(const std::vector<std::string>& argv) {
  Args args(argv, {}, {"--verbose"});
  if (args.positional().empty()) throw Error("missing argument DIR (a task directory)");
  bool ok = true;
  // Never throws for a path it cannot read (checkTaskDir reports that as the directory's error).
  auto isDir = [](const fs::path& p) {
    std::error_code ec;
    return fs::is_directory(p, ec);
  };
  auto exists = [](const fs::path& p) {
    std::error_code ec;
    return fs::symlink_status(p, ec).type() != fs::file_type::not_found;
  };
  for (const auto& path : args.positional()) {
    // The output of `ddace generate` holds train/ and test/: validate both.
    if (!exists(fs::path(path) / "task.yaml") && isDir(fs::path(path) / "train")) {
      for (const char* sub : {"train", "test"})
        if (isDir(fs::path(path) / sub)) ok = validateOne((fs::path(path) / sub).string(), args.has("--verbose")) && ok;
    } else {
      ok = validateOne(path, args.has("--verbose")) && ok;
    }
  }
  return ok ? 0 : 1;
}

DDACE_COMMAND({"validate", "ddace validate DIR... [--verbose]",
               "check task directories against ddace-task/1; print a summary or every error "
               "as file:line:column",
               runValidate});

}  // namespace
}  // namespace ddace::cli
