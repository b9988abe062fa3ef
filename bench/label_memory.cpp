// bench_label_memory: peak memory of `ddace label` on a long recording (about 200 MB)
// against a short one measured in the same run.
//
// A Task 4 demonstration moved by a person (label::humanMotion, seed 1) is played forward
// and backward in turn (the robots drive back to where they started, so the recording is
// one continuous motion) until the CSV is about 200 MB, without labels; the reference is
// one forward and one backward play. Each is labelled
//   - in this process as `ddace label` does it (the check, pass 1 into a TokenSpill,
//     pass 2, the read-back), the peak resident set (VmHWM) reset before each;
//   - by the `ddace label` tool built next to this benchmark, in a child process (its
//     peak resident set from wait4).
// Both passes stream the file: memory holds a few seconds of rows and of motions, the
// inferred tokens go to a temporary file, the read-back check counts the steps: nothing
// grows with the recording's rows or steps.
// Writes docs/bench/label_memory.md under the repository it finds at run time (--repo DIR).
// Usage: ddace bench label_memory [--repo DIR] [--mb N], or the binary bench_label_memory
// with the same options (N: the long recording's size in MiB,
// about: later plays have longer times, some 4 % more; default 200. --mb 1024: a 1 GiB
// recording, some 3.5 GB of scratch space and minutes).
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/label/human_motion.h"
#include "ddace/label/recording.h"
#include "ddace/task/summary.h"
#include "ddace/tasks/generators.h"
#include "peak_memory.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

constexpr std::uint64_t kDefaultMb = 200;

struct Measure {
  long peak_kb = 0;
  double seconds = 0;
  size_t steps = 0, tokens = 0;
};

Measure labelInProcess(const std::string& dir, const task::TaskSpec& spec, bool& reset_ok) {
  Measure m;
  reset_ok = bench::resetPeak() && reset_ok;
  const auto t0 = std::chrono::steady_clock::now();
  const std::string csv = dir + "/demos/demo_000.csv", labelled = dir + "/labelled.csv";
  // What `ddace label` runs on one recording: the check, pass 1 into a spill, pass 2, the read-back.
  task::summarizeDemonstrationCsv(csv, spec);
  label::TokenSpill spill;
  const label::RecordingInference inf = label::inferRecording(
      csv, spec, nullptr, [&](label::InferredStep&& s) { spill.add(s); }, [](label::Note&&) {});
  {
    OutputFile out(labelled);
    label::LabelCursor cursor(spill.reader(0, spill.size()), spec.entities.size());
    label::writeLabelledRecording(csv, spec, inf.labelled, cursor, out.stream());
    out.commit();
  }
  const task::DemonstrationSummary back = task::summarizeDemonstrationCsv(labelled, spec, false);
  if (back.step_count != inf.steps)
    throw Error(labelled + " reads back with " + std::to_string(back.step_count) + " steps, inferred " +
                std::to_string(inf.steps));
  m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  m.peak_kb = bench::statusKb("VmHWM");
  m.steps = inf.steps;
  m.tokens = inf.tokens;
  fs::remove(labelled);
  return m;
}

/// `ddace label DIR --out DIR-out` in a child process (its stderr in DIR-stderr.txt).
Measure labelTool(const fs::path& tool, const std::string& dir, int& status) {
  const bench::ChildRun run =
      bench::runChild({tool.string(), "label", dir, "--out", dir + "-out"}, dir + "-stderr.txt");
  Measure m;
  m.peak_kb = run.peak_kb;
  m.seconds = run.seconds;
  status = run.status;
  return m;
}

/// DIR/task.yaml and DIR/demos/demo_000.csv: `demo` played forward and backward `plays`
/// times each, without labels. Returns the CSV's size.
std::uint64_t writePlays(const task::Demonstration& demo, const task::TaskSpec& spec, const std::string& dir,
                         size_t plays) {
  fs::create_directories(dir + "/demos");
  writeTextFile(dir + "/task.yaml", task::taskYamlText(spec));
  OutputFile out(dir + "/demos/demo_000.csv");
  std::string line = "t";
  for (const auto& e : spec.entities) line += "," + e.name + ".x," + e.name + ".y";
  out.stream() << line << "\n";
  const size_t n = demo.rows();
  const double period = demo.t.back() + 1.0 / 30;
  char buf[64];
  for (size_t k = 0; k < 2 * plays; ++k)
    for (size_t i = 0; i < n; ++i) {
      const size_t r = k % 2 ? n - 1 - i : i;
      std::snprintf(buf, sizeof buf, "%.6f", static_cast<double>(k) * period + demo.t[i]);
      line = buf;
      for (const auto& p : demo.positions[r]) {
        std::snprintf(buf, sizeof buf, ",%.6f,%.6f", p.x(), p.y());
        line += buf;
      }
      out.stream() << line << "\n";
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
    std::uint64_t target_mb = kDefaultMb;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--mb" && i + 1 < argc) {
        const long v = std::atol(argv[++i]);
        if (v < 1 || v > 65536) throw Error("--mb must be a size in MB, 1..65536 (got '" + std::string(argv[i]) + "')");
        target_mb = static_cast<std::uint64_t>(v);
      } else {
        throw Error("usage: bench_label_memory [--repo DIR] [--mb N]");
      }
    }
    const std::uint64_t target_bytes = target_mb << 20;
    const std::string load = loadAverage();
    const bench::ScratchDir scratch("ddace_bench_label_memory");
    const fs::path& work = scratch.path();

    tasks::GeneratorOptions o;
    o.family = "task4";
    o.demos = 1;
    const task::TaskDir source = tasks::generate(o);
    SplitMix64 rng(1);
    const task::Demonstration demo = label::humanMotion(source.demos[0], source.spec, {}, rng);
    const std::string small = (work / "small").string(), big = (work / "big").string();
    const std::uint64_t small_bytes = writePlays(demo, source.spec, small, 1);
    const size_t plays = static_cast<size_t>(target_bytes / small_bytes) + 1;
    std::cout << "writing a " << bench::mb(static_cast<long>(target_bytes >> 10)) << " MB recording (" << plays
              << " plays forward and back)\n"
              << std::flush;
    const std::uint64_t big_bytes = writePlays(demo, source.spec, big, plays);

    bool reset_ok = true;
    const Measure small_in = labelInProcess(small, source.spec, reset_ok);
    const Measure big_in = labelInProcess(big, source.spec, reset_ok);
    int small_status = -1, big_status = -1;
    const bool have_tool = fs::exists(tool);
    Measure small_tool, big_tool;
    if (have_tool) {
      small_tool = labelTool(tool, small, small_status);
      big_tool = labelTool(tool, big, big_status);
      for (const auto& [status, dir] : {std::pair{small_status, small}, std::pair{big_status, big}})
        if (status != 0)
          throw Error("ddace label failed on the generated recording " + dir + ": " +
                      readTextFile(dir + "-stderr.txt"));
    }
    const long growth_kb = big_in.peak_kb - small_in.peak_kb;
    const double per_token =
        big_in.tokens > small_in.tokens ? growth_kb * 1024.0 / static_cast<double>(big_in.tokens - small_in.tokens) : 0;
    // Goal: memory independent of the recording (its rows and its steps): the peak grows
    // by less than 1 % of the long recording's size (as csv_memory for `ddace validate`).
    const bool met = reset_ok && growth_kb * 1024.0 < 0.01 * static_cast<double>(big_bytes);
    std::ostringstream md;
    md << "# Peak memory of labelling a long recording\n\n"
       << "Written by `ddace bench label_memory --mb " << target_mb
       << "` (bench/label_memory.cpp; the goal's 1 GiB: `--mb 1024`). Do not edit.\n\n"
       << "A Task 4 demonstration moved by a person (`label::humanMotion`, seed 1, " << demo.rows()
       << " rows at 30 Hz) played forward and backward in turn, without labels: once (the reference) and " << plays
       << " times (the long recording), in the same run. In process: what `ddace label` runs on a recording (the "
          "check, `label::inferRecording` into a `label::TokenSpill`, `label::writeLabelledRecording`, the read-back "
          "check), peak resident set (VmHWM) reset before each. "
          "Tool: `ddace label DIR --out OUT` in a child process, peak resident set from wait4. "
       << utcNow() << ", 1-minute load average at the start: " << load << ".\n\n"
       << "| recording | CSV size | inferred steps | tokens | in process: peak RSS (MB) | in process: wall (s) "
          "| `ddace label`: peak RSS (MB) | `ddace label`: wall (s) |\n"
       << "|---|---:|---:|---:|---:|---:|---:|---:|\n";
    auto row = [&](const char* name, std::uint64_t bytes, const Measure& in, const Measure& t) {
      md << "| " << name << " | " << bench::fixed(bytes / 1048576.0, 1) << " MB | " << in.steps << " | " << in.tokens
         << " | " << bench::mb(in.peak_kb) << " | " << bench::fixed(in.seconds, 2) << " | "
         << (have_tool ? bench::mb(t.peak_kb) : "not built") << " | " << (have_tool ? bench::fixed(t.seconds, 2) : "")
         << " |\n";
    };
    row("one play forward and back (reference)", small_bytes, small_in, small_tool);
    row("long", big_bytes, big_in, big_tool);
    md << "\nPeak growth from the reference to the long recording: " << bench::mb(growth_kb) << " MB in process, "
       << bench::fixed(per_token, 0) << " bytes per inferred token";
    if (have_tool) md << "; " << bench::mb(big_tool.peak_kb - small_tool.peak_kb) << " MB for the tool";
    if (have_tool && small_tool.peak_kb > 0)
      md << " (the tool's peak " << bench::fixed(static_cast<double>(big_tool.peak_kb) / small_tool.peak_kb, 2)
         << "x the reference's)";
    md << ".\n\nGoal (a 1 GiB recording labels with bounded memory): memory independent of the "
          "recording's rows and steps, i.e. the peak in process grows by less than 1 % of the long recording's "
          "size (this recording, a motion every 1.5 s, is denser in motions than a person's): "
       << (met ? "met" : (reset_ok ? "NOT met" : "not measured (the kernel cannot reset VmHWM)")) << ".\n";
    std::cout << md.str();
    bench::writeResults(repo, "label_memory", md.str());
    return met ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "bench_label_memory: " << e.what() << "\n";
    return 1;
  }
}
