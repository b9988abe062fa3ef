// bench_csv_memory: peak memory of validating a large demonstration CSV (about 200 MB)
// against a 2-row file measured in the same run.
//
// A generated Task 4 demonstration is stretched, each of its rows repeated with its
// positions and labels at finely spaced times (a long, finely sampled recording with the
// same steps), into a task directory in a temporary folder; a second directory holds the
// same task with a 2-row demonstration. Each is validated
//   - in this process by task::summarizeTaskDir (what `ddace validate` runs), the peak
//     resident set (VmHWM) reset before each (/proc/self/clear_refs);
//   - by the `ddace validate` tool built next to this benchmark, in a child process
//     (its peak resident set from wait4).
// The readers stream the CSV (task/demonstration.h): the peak must not grow with the rows.
// Writes docs/bench/csv_memory.md under the repository it finds at run time (--repo DIR, see bench/results.h).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/task/summary.h"
#include "ddace/tasks/generators.h"
#include "peak_memory.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

constexpr std::uint64_t kTargetBytes = std::uint64_t{200} << 20;

struct Measure {
  long peak_kb = 0;   ///< peak resident set while validating
  long start_kb = 0;  ///< resident set before
  double seconds = 0;
  size_t rows = 0;
  size_t errors = 0;
};

Measure validateInProcess(const std::string& dir, bool& reset_ok) {
  Measure m;
  reset_ok = bench::resetPeak() && reset_ok;
  m.start_kb = bench::statusKb("VmRSS");
  const auto t0 = std::chrono::steady_clock::now();
  const task::TaskDirSummary summary = task::summarizeTaskDir(dir);
  m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.peak_kb = bench::statusKb("VmHWM");
  m.errors = summary.errors.size();
  for (const auto& d : summary.demos) m.rows += d.rows;
  for (const auto& e : summary.errors) std::cerr << e.str() << "\n";
  return m;
}

/// `ddace validate DIR` in a child process: its peak resident set (kB) and exit status.
Measure validateTool(const fs::path& tool, const std::string& dir, int& status) {
  const bench::ChildRun run = bench::runChild({tool.string(), "validate", dir});
  Measure m;
  m.peak_kb = run.peak_kb;
  m.seconds = run.seconds;
  status = run.status;
  return m;
}

/// Writes DIR/task.yaml and DIR/demos/demo_000.csv: the demonstration's rows, each one
/// repeated `repeat` times at times spaced evenly up to the next row. Returns the CSV size.
std::uint64_t writeStretched(const task::TaskDir& source, const std::string& dir, size_t repeat, size_t max_rows) {
  fs::create_directories(dir + "/demos");
  writeTextFile(dir + "/task.yaml", task::taskYamlText(source.spec));
  const task::Demonstration& demo = source.demos.at(0);
  std::istringstream text(task::demonstrationCsvText(demo, source.spec));
  std::string header, line;
  std::getline(text, header);
  std::vector<std::string> rest;  // each row after its t
  while (std::getline(text, line)) rest.push_back(line.substr(line.find(',')));
  OutputFile out(dir + "/demos/demo_000.csv");
  out.stream() << header << "\n";
  size_t rows = 0;
  char t[32];
  for (size_t i = 0; i < rest.size() && rows < max_rows; ++i) {
    const bool last = i + 1 == rest.size();
    const double t0 = demo.t[i], dt = last ? 0.0 : (demo.t[i + 1] - demo.t[i]) / static_cast<double>(repeat);
    for (size_t k = 0; k < (last ? 1 : repeat) && rows < max_rows; ++k, ++rows) {
      std::snprintf(t, sizeof t, "%.9f", t0 + dt * static_cast<double>(k));
      out.stream() << t << rest[i] << "\n";
    }
  }
  out.commit();
  return fs::file_size(dir + "/demos/demo_000.csv");
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const fs::path self = fs::read_symlink("/proc/self/exe");
    const fs::path tool = self.parent_path() / "ddace";
    const fs::path repo = bench::repositoryFromArgs(argc, argv);
    bench::noOtherOptions(argc, argv, "bench_csv_memory");
    const std::string load = loadAverage();
    const bench::ScratchDir scratch("ddace_bench_csv_memory");
    const fs::path& work = scratch.path();

    tasks::GeneratorOptions o;
    o.family = "task4";
    o.demos = 1;
    o.seed = 1;
    const task::TaskDir source = tasks::generate(o);
    const std::string small = (work / "small").string(), big = (work / "big").string();
    const std::uint64_t small_bytes = writeStretched(source, small, 1, 2);
    // One pass at 1 repeat gives the bytes per row; then enough repeats for the target.
    const std::uint64_t one = writeStretched(source, big, 1, static_cast<size_t>(-1));
    const size_t repeat = static_cast<size_t>(kTargetBytes / one) + 1;
    std::cout << "writing a " << bench::mb(static_cast<long>(kTargetBytes >> 10)) << " MB demonstration (each of "
              << source.demos[0].rows() << " rows x" << repeat << ")\n"
              << std::flush;
    const std::uint64_t big_bytes = writeStretched(source, big, repeat, static_cast<size_t>(-1));

    bool reset_ok = true;
    const Measure small_in = validateInProcess(small, reset_ok);
    const Measure big_in = validateInProcess(big, reset_ok);
    int small_status = -1, big_status = -1;
    const bool have_tool = fs::exists(tool);
    Measure small_tool, big_tool;
    if (have_tool) {
      small_tool = validateTool(tool, small, small_status);
      big_tool = validateTool(tool, big, big_status);
    }
    if (small_in.errors || big_in.errors || (have_tool && (small_status != 0 || big_status != 0)))
      throw Error("a generated file did not validate (errors above)");

    // Goal: the peak grows by less than 1% of the file's size (it is streamed).
    const long growth_kb = big_in.peak_kb - small_in.peak_kb;
    const bool met = reset_ok && growth_kb * 1024.0 < 0.01 * static_cast<double>(big_bytes);
    std::ostringstream md;
    md << "# Peak memory of validating a large demonstration CSV\n\n"
       << "Written by `bench_csv_memory` (bench/csv_memory.cpp; `ddace bench csv_memory`). Do not edit.\n\n"
       << "A generated Task 4 demonstration (seed 1, " << source.demos[0].rows() << " rows, "
       << source.spec.entities.size() << " entities) stretched to " << big_in.rows << " rows: each row repeated "
       << repeat << " times at evenly spaced times up to the next (the same steps, sampled finely). "
       << "The reference is the same task with a 2-row demonstration, in the same run. "
       << "In process: `task::summarizeTaskDir` (what `ddace validate` runs), peak resident set "
       << "(VmHWM) reset before each file. Tool: `ddace validate DIR` in a child process, peak "
       << "resident set from wait4. " << utcNow() << ", 1-minute load average at the start: " << load << ".\n\n"
       << "| demonstration | CSV size | rows | in process: peak RSS (MB) | in process: wall (s) "
          "| `ddace validate`: peak RSS (MB) | `ddace validate`: wall (s) |\n"
       << "|---|---:|---:|---:|---:|---:|---:|\n";
    auto row = [&](const char* name, std::uint64_t bytes, const Measure& in, const Measure& t) {
      md << "| " << name << " | "
         << (bytes < (1u << 20) ? std::to_string(bytes) + " bytes" : bench::fixed(bytes / 1048576.0, 1) + " MB")
         << " | " << in.rows << " | " << bench::mb(in.peak_kb) << " | " << bench::fixed(in.seconds, 2) << " | "
         << (have_tool ? bench::mb(t.peak_kb) : "not built") << " | " << (have_tool ? bench::fixed(t.seconds, 2) : "")
         << " |\n";
    };
    row("2 rows (reference)", small_bytes, small_in, small_tool);
    row("stretched", big_bytes, big_in, big_tool);
    md << "\nPeak growth from the 2-row file to the " << bench::fixed(big_bytes / 1048576.0, 0)
       << " MB file: " << bench::mb(growth_kb) << " MB in process ("
       << bench::fixed(static_cast<double>(big_in.peak_kb) / static_cast<double>(small_in.peak_kb), 2) << "x)";
    if (have_tool)
      md << ", " << bench::mb(big_tool.peak_kb - small_tool.peak_kb) << " MB for the tool ("
         << bench::fixed(static_cast<double>(big_tool.peak_kb) / static_cast<double>(small_tool.peak_kb), 2) << "x)";
    md << ".\n\nGoal: memory independent of the number of rows, i.e. the peak grows by less than 1% "
          "of the file's size: "
       << (met ? "met" : (reset_ok ? "NOT met" : "not measured (the kernel cannot reset VmHWM)")) << ".\n";
    std::cout << md.str();
    bench::writeResults(repo, "csv_memory", md.str());
    return met ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "bench_csv_memory: " << e.what() << "\n";
    return 1;
  }
}
