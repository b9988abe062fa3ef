// ddace table: regenerate the paper's Table 2 (and Fig. 4, the case studies and one
// trajectory overlay per task) from scratch, writing docs/results.md. Every number in
// that file comes from this run.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include "command.h"
#include "ddace/common/repository.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/label/human_motion.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"
#include "ddace/pipeline/evaluation.h"
#include "results_discussion.h"

namespace ddace::cli {
namespace {

using namespace ddace::pipeline;

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Settings {
  fs::path out, docs;
  bool quick = false;
  int train = 30, test = 15, seed = 1;
  int max_epochs = 0;  ///< 0: the trainer's default (train to the plateau)
  int gnn_epochs = 0;  ///< cap for the gnn baseline only (0: as every other model)
  int jobs = 1;        ///< models trained at a time, one process each (single-threaded, deterministic)
  int zoo_rules = 50;  ///< the section "Rule zoo": the first this many distinct rules (0: no section)
};

/// Human-timed training demonstrations: label onsets up to this late, seconds, and this
/// position noise, metres (issue: "demonstrations as people make them").
constexpr double kHumanOnsetJitter = 0.4;
constexpr double kHumanNoise = 0.002;
/// The closed-loop rows: differential-drive robots steered by the path follower's control
/// law from positions measured with this much Gaussian noise, metres (the tracker's order).
constexpr double kClosedLoopNoise = 0.002;
/// The section "Labels inferred from motion": training seeds per training set (--seed and
/// the next ones). Three: each model is itself a vote of three networks where the scene
/// decides (docs/tgn.md, "Ensemble"), which already narrows the spread over seeds.
constexpr int kLabelSeeds = 3;

/// The paper's Table 2 (OSR / SSR / GCR / FD), for the paper column.
std::string paperRow(const std::string& family, const std::string& variant) {
  static const std::map<std::string, std::map<std::string, std::string>> table = {
      {"paper",
       {{"task1", "1 / 1 / 1 / 0.02"},
        {"task2", "1 / 1 / 1 / 0"},
        {"task3", "1 / 1 / 1 / 0"},
        {"task4", "1 / 1 / 1 / 0.04"}}},
      {"full-graph",
       {{"task1", "0 / 0.2 / 0.74 / 0.02"},
        {"task2", "0 / 0.3 / 0.59 / 0"},
        {"task3", "0 / 0.25 / 0.50 / 0"},
        {"task4", "0 / 0.5 / 0.74 / 0.04"}}},
      {"gnn",
       {{"task1", "0 / 0 / 0.33 / 0.67"},
        {"task2", "0 / 0 / 0.18 / 1"},
        {"task3", "0 / 0 / 0.16 / 0.93"},
        {"task4", "0 / 0 / 0.25 / 1"}}},
      {"llm",
       {{"task1", "1 / 1 / 1 / –"},
        {"task2", "0 / 0.5 / 0.64 / –"},
        {"task3", "0 / 0.25 / 0.25 / –"},
        {"task4", "1 / 1 / 1 / –"}}},
  };
  const auto v = table.find(variant);
  if (v == table.end()) return "(not in the paper)";
  const auto f = v->second.find(family);
  return f == v->second.end() ? "(not in the paper)" : f->second;
}

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Generates (once) a task directory pair and returns DIR (holding train/ and test/).
fs::path dataset(const Settings& s, const std::string& name, tasks::GeneratorOptions o, int train, int test) {
  const fs::path dir = s.out / "data" / name;
  o.seed = s.seed;
  o.demos = train;
  task::writeTaskDir(tasks::generate(o), (dir / "train").string());
  o.demos = test;
  o.seed = s.seed * 2654435761ULL + 0x7e57;  // as `ddace generate`: fresh test configurations
  o.jitter_m = 0;
  o.mislabel_fraction = 0;
  o.onset_jitter_s = 0;
  task::writeTaskDir(tasks::generate(o), (dir / "test").string());
  return dir;
}

struct Row {
  std::string task;
  tgn::Variant variant = tgn::Variant::Scene;
  std::string condition;
  eval::Summary m;
  double train_s = 0;
  int epochs = 0;
  std::string stop;
  int demos = 0;
  /// How many observed edges each refinement rule decided: recurs, same cluster, rare, crosses clusters.
  int rules[4] = {0, 0, 0, 0};
  /// The same model on the same test set in closed loop (Job::closed_loop), else trials 0.
  eval::Summary closed;
  /// ... with bodies, with and without the safety filter (Job::bodies), else trials 0.
  eval::Summary bodies, unfiltered;
};

/// The E' decisions of a model, counted per rule.
void countRules(const graph::RefinedGraph& g, int* rules) {
  for (const auto& e : g.edges) ++rules[static_cast<int>(e.decision)];
}

/// Trains one model on data/train, evaluates it on data/test. `overlay`: also write the
/// first trial's paths for the trajectory overlay figure.
Row trainAndEvaluate(const Settings& s, const fs::path& data, const std::string& model_name, const std::string& family,
                     tgn::Variant variant, const std::string& condition, bool overlay, bool closed_loop, bool bodies,
                     bool bodies_unfiltered, std::optional<int> train_seed) {
  const task::TaskDir train = task::loadTaskDir((data / "train").string());
  const task::TaskDir test = task::loadTaskDir((data / "test").string());
  tgn::TrainOptions opt;
  opt.variant = variant;
  opt.seed = static_cast<uint64_t>(train_seed.value_or(s.seed));
  if (s.max_epochs > 0) opt.max_epochs = s.max_epochs;
  if (opt.variant == tgn::Variant::Gnn && s.gnn_epochs > 0) opt.max_epochs = std::min(opt.max_epochs, s.gnn_epochs);
  const auto t0 = Clock::now();
  const Model model = trainModel(train, opt, (s.out / "models" / model_name).string(), nullptr);
  Row r;
  r.train_s = secondsSince(t0);
  r.task = family;
  r.variant = variant;
  r.demos = static_cast<int>(train.demos.size());
  countRules(model.sequence.info().refined, r.rules);
  r.condition = condition;
  r.epochs = static_cast<int>(model.sequence.info().history.size());
  r.stop = model.sequence.info().stop_reason;
  const Evaluation e = evaluate(model, test, {});
  r.m = e.summary;
  writeTextFile((s.out / "eval" / (model_name + ".json")).string(), evaluationJson(e));
  if (closed_loop) {
    EvalOptions o;
    o.execution = "diffdrive";
    o.bodies = false;  // this section's robots are points; the section "Bodies" has bodies
    o.noise_m = kClosedLoopNoise;
    o.seed = static_cast<uint64_t>(s.seed);
    const Evaluation c = evaluate(model, test, o);
    r.closed = c.summary;
    writeTextFile((s.out / "eval" / (model_name + "-diffdrive.json")).string(), evaluationJson(c));
  }
  if (bodies) {
    EvalOptions o;
    o.execution = "diffdrive";
    o.noise_m = kClosedLoopNoise;
    o.seed = static_cast<uint64_t>(s.seed);
    for (const bool filter : {true, false}) {
      if (!filter && !bodies_unfiltered) continue;
      o.safety_filter = filter;
      const Evaluation b = evaluate(model, test, o);
      (filter ? r.bodies : r.unfiltered) = b.summary;
      writeTextFile((s.out / "eval" / (model_name + (filter ? "-bodies.json" : "-bodies-unfiltered.json"))).string(),
                    evaluationJson(b));
    }
  }
  // The first trial's paths, for the trajectory overlay figure.
  if (!e.trials.empty() && overlay) {
    std::ofstream csv((s.out / "overlays" / (family + ".csv")).string());
    csv << "kind,token,index,x,y\n";
    const auto& gt = test.demos.front();
    for (const auto& seg : gt.segments)
      if (seg.token.isMotion()) {
        const auto p = gt.segmentPath(seg);
        for (size_t i = 0; i < p.size(); ++i)
          csv << "demonstrated," << task::tokenKey(seg.token, test.spec) << "," << i << "," << p[i].x() << ","
              << p[i].y() << "\n";
      }
    for (const auto& ex : e.trials.front().executed)
      for (size_t i = 0; i < ex.planned.size(); ++i)
        csv << "generated," << task::tokenKey(ex.token, test.spec) << "," << i << "," << ex.planned[i].x() << ","
            << ex.planned[i].y() << "\n";
  }
  std::printf("  %-12s %-10s %-26s OSR %.3f SSR %.3f GCR %.3f FD %.4f  (%d epochs, %s, %.1f s)\n", r.task.c_str(),
              tgn::toString(variant), condition.c_str(), r.m.osr, r.m.ssr, r.m.gcr, r.m.fd, r.epochs, r.stop.c_str(),
              r.train_s);
  std::fflush(stdout);
  return r;
}

/// One model of the table: trained on data/train, evaluated on data/test.
struct Job {
  fs::path data;
  std::string model_name, family;
  tgn::Variant variant = tgn::Variant::Scene;
  std::string condition;
  bool overlay = false;
  bool closed_loop = false;                      ///< also run the test set on the differential-drive simulation
  bool bodies = false;                           ///< also run it with bodies, with and without the safety filter
  std::optional<int> train_seed = std::nullopt;  ///< the training seed; unset: the table's (--seed)
  bool bodies_unfiltered = true;                 ///< with bodies: also without the filter
};

/// A row through a file, from the job's process to the table's.
void writeRow(const fs::path& path, const Row& r) {
  std::ofstream out(path);
  out << std::setprecision(17) << r.task << "\n"
      << tgn::toString(r.variant) << "\n"
      << r.condition << "\n"
      << r.stop << "\n"
      << r.m.trials << " " << r.m.osr << " " << r.m.ssr << " " << r.m.gcr << " " << r.m.fd << " " << r.m.fd_tokens
      << " " << r.train_s << " " << r.epochs << " " << r.demos << " " << r.rules[0] << " " << r.rules[1] << " "
      << r.rules[2] << " " << r.rules[3] << "\n"
      << r.closed.trials << " " << r.closed.osr << " " << r.closed.ssr << " " << r.closed.gcr << " " << r.closed.fd
      << "\n";
  for (const eval::Summary* b : {&r.bodies, &r.unfiltered})
    out << b->trials << " " << b->osr << " " << b->gcr << " " << b->collisions << " " << b->trials_with_collision << " "
        << b->min_clearance_m << " " << b->makespan_s << " " << b->fd << "\n";
  if (!out) throw Error(Diagnostic{path.string(), 0, 0, "cannot write"});
}

Row readRow(const fs::path& path) {
  std::ifstream in(path);
  Row r;
  std::string fd, closed_fd;  // "nan" when no motion token matched: not readable by operator>>
  std::getline(in, r.task);
  std::string variant;
  std::getline(in, variant);
  r.variant = tgn::variantFromString(variant);
  std::getline(in, r.condition);
  std::getline(in, r.stop);
  in >> r.m.trials >> r.m.osr >> r.m.ssr >> r.m.gcr >> fd >> r.m.fd_tokens >> r.train_s >> r.epochs >> r.demos >>
      r.rules[0] >> r.rules[1] >> r.rules[2] >> r.rules[3] >> r.closed.trials >> r.closed.osr >> r.closed.ssr >>
      r.closed.gcr >> closed_fd;
  if (!in) throw Error(Diagnostic{path.string(), 0, 0, "not a complete result row"});
  r.m.fd = std::strtod(fd.c_str(), nullptr);
  r.closed.fd = std::strtod(closed_fd.c_str(), nullptr);
  for (eval::Summary* b : {&r.bodies, &r.unfiltered}) {
    std::string clearance, fd;  // "nan" when no two bodies were measured, no motion token matched
    in >> b->trials >> b->osr >> b->gcr >> b->collisions >> b->trials_with_collision >> clearance >> b->makespan_s >>
        fd;
    if (!in) throw Error(Diagnostic{path.string(), 0, 0, "not a complete result row (bodies)"});
    b->min_clearance_m = std::strtod(clearance.c_str(), nullptr);
    b->fd = std::strtod(fd.c_str(), nullptr);
  }
  return r;
}

/// Runs every job in a process of its own, s.jobs at a time; rows come back in the jobs'
/// order. A process per model, because two models trained side by side in one process are
/// not bit-for-bit reproducible (observed: the gnn baseline diverged after 35 epochs from the
/// same model trained alone), and every model here trains single-threaded from its own seed,
/// so the numbers do not depend on s.jobs. This process has not touched libtorch when it
/// forks. The gnn baseline's jobs are the longest and start first.
std::vector<Row> runJobs(const Settings& s, const std::vector<Job>& jobs) {
  std::vector<size_t> order(jobs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_partition(order.begin(), order.end(), [&](size_t i) { return jobs[i].variant == tgn::Variant::Gnn; });
  const fs::path row_dir = s.out / "rows";
  fs::create_directories(row_dir);
  auto row_file = [&](size_t i) { return row_dir / (jobs[i].model_name + ".txt"); };
  std::map<pid_t, size_t> running;
  // On an error here, no job process outlives the table: they are stopped and reaped.
  struct Reaper {
    std::map<pid_t, size_t>& running;
    ~Reaper() {
      for (const auto& [pid, job] : running) ::kill(pid, SIGTERM);
      for (const auto& [pid, job] : running) ::waitpid(pid, nullptr, 0);
    }
  } reaper{running};
  std::vector<std::string> failed;
  size_t next = 0;
  while (next < order.size() || !running.empty()) {
    while (next < order.size() && static_cast<int>(running.size()) < s.jobs) {
      const size_t i = order[next++];
      fs::remove(row_file(i));
      std::cout.flush();
      std::fflush(stdout);
      const pid_t pid = fork();
      if (pid < 0) throw Error(std::string("ddace table: cannot start a job process: ") + std::strerror(errno));
      if (pid == 0) {
        int rc = 0;
        try {
          const Job& j = jobs[i];
          writeRow(row_file(i), trainAndEvaluate(s, j.data, j.model_name, j.family, j.variant, j.condition, j.overlay,
                                                 j.closed_loop, j.bodies, j.bodies_unfiltered, j.train_seed));
        } catch (const std::exception& e) {
          std::fprintf(stderr, "ddace table: %s: %s\n", jobs[i].model_name.c_str(), e.what());
          rc = 1;
        }
        std::fflush(stdout);
        std::fflush(stderr);
        _exit(rc);
      }
      running[pid] = i;
    }
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      throw Error(std::string("ddace table: waiting for a job: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    if (WIFSIGNALED(status))
      std::fprintf(stderr, "ddace table: %s: the job process was killed (%s)\n", jobs[it->second].model_name.c_str(),
                   strsignal(WTERMSIG(status)));
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) failed.push_back(jobs[it->second].model_name);
    running.erase(it);
  }
  if (!failed.empty()) {
    std::string names;
    for (const auto& f : failed) names += (names.empty() ? "" : ", ") + f;
    throw Error("ddace table: these models failed (see above): " + names);
  }
  std::vector<Row> rows;
  for (size_t i = 0; i < jobs.size(); ++i) rows.push_back(readRow(row_file(i)));
  return rows;
}

std::string fmt(double v, int digits = 3) {
  if (!std::isfinite(v)) return "–";
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

int plot_failures = 0;

void runPlot(const std::string& command) {
  const int rc = std::system(command.c_str());
  if (rc != 0) {
    std::cerr << "ddace table: plotting failed (" << rc << "): " << command << "\n";
    ++plot_failures;
  }
}

/// The vector instruction set libtorch's CPU kernels use in every job. Its kernels for one
/// ISA and another round differently in the last bits (measured: the gnn baseline's loss on
/// Task 1 differs from the first epoch between the AVX2 and the scalar kernels), and the
/// GNN's long training amplifies that into other epochs and other rows; without this the
/// table's numbers depend on the host's CPU. Children (jobs, plot_loss.py's trainings)
/// inherit it; a CPU without AVX2 falls back to its best and the table says which it used.
constexpr const char* kCpuCapability = "avx2";

/// Which OpenBLAS kernels the jobs use, as the results record it (the environment decides:
/// `OPENBLAS_CORETYPE`, else OpenBLAS's own choice for the processor).
std::string openBlasKernel() {
  const char* core = std::getenv("OPENBLAS_CORETYPE");
  return core && *core ? std::string("kernels: `OPENBLAS_CORETYPE=") + core + "` (from the environment)"
                       : std::string("kernels: chosen by OpenBLAS for this processor (`OPENBLAS_CORETYPE` unset)");
}

int hardwareCores() {
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}  // 0: unknown

/// The command line: where to write, how much to run.
Settings parseSettings(const Args& args, const fs::path& source) {
  Settings s;
  s.quick = args.has("--quick");
  s.out = args.get("--out", (source / "out" / (s.quick ? "table-quick" : "table")).string());
  // A smoke test must not overwrite the shipped results: --quick writes beside its models.
  s.docs = args.get("--docs", s.quick ? (s.out / "docs").string() : (source / "docs").string());
  const long seed = args.getInt("--seed", 1);
  if (seed < 0 || seed > 1000000000) throw Error("--seed must be in [0, 1e9]");
  s.seed = static_cast<int>(seed);
  s.gnn_epochs = static_cast<int>(args.getInt("--gnn-epochs", 0));
  if (s.gnn_epochs < 0) throw Error("--gnn-epochs must not be negative");
  s.jobs = static_cast<int>(args.getInt("--jobs", hardwareCores()));
  if (s.jobs < 1) throw Error("--jobs must be at least 1");
  s.zoo_rules = static_cast<int>(args.getInt("--zoo-rules", 50));
  if (s.zoo_rules < 0) throw Error("--zoo-rules must not be negative");
  if (s.quick) {  // a smoke test of the whole command, not the paper's protocol
    s.zoo_rules = std::min(s.zoo_rules, 2);
    s.train = 5;
    s.test = 3;
    s.max_epochs = 40;
  }
  return s;
}

/// One family's demonstrations of the section "Labels inferred from motion".
struct LabelRow {
  std::string family;
  int demos = 0;
  label::LabelScore score;
  std::vector<size_t> truth_jobs, inferred_jobs;  ///< one per training seed, in seed order
};

/// Every model of a run, and which of them each section of the results reads (indices into
/// jobs, which are the rows' indices too).
struct Plan {
  std::vector<Job> jobs;
  std::vector<size_t> table2, few, human, imperfect, labels, zoo, zoo_direct, kinds;
  std::vector<int> sizes;  ///< demonstrations per training set
  int label_seeds = kLabelSeeds;
  std::vector<LabelRow> label_rows;
  std::vector<tasks::ZooRule> zoo_rules;  ///< OSR of rule k at sizes[m] is rows[zoo[k * sizes.size() + m]]
  std::string zoo_undrawable;             ///< rules the direct motion cannot demonstrate
  std::vector<tasks::ZooKind> kind_list;  ///< OSR of kind k at sizes[m] is rows[kinds[k * sizes.size() + m]]

  void add(std::vector<size_t>& section, Job j) {
    section.push_back(jobs.size());
    jobs.push_back(std::move(j));
  }
};

const tgn::Variant kDefaultVariant = tgn::TrainOptions{}.variant;
/// The paper's network, the default, the ablation, the baseline.
const std::vector<tgn::Variant> kVariants = {tgn::Variant::Paper, tgn::Variant::Scene, tgn::Variant::FullGraph,
                                             tgn::Variant::Gnn};

/// Quick: a smoke test of every kind of row, not every combination.
std::vector<std::string> humanFamilies(const Settings& s) {
  return s.quick ? std::vector<std::string>{"task4"} : tasks::paperFamilies();
}

/// Table 2, "Few-shot, every family", "Human-timed demonstrations", "Imperfect demonstrations".
void planFamilies(const Settings& s, Plan& p) {
  for (const auto& f : tasks::paperFamilies()) {
    tasks::GeneratorOptions o;
    o.family = f;
    const fs::path data = dataset(s, f, o, s.train, s.test);
    for (const auto& v : kVariants)
      p.add(p.table2,
            {data, f + "-" + tgn::toString(v), f, v, std::to_string(s.train) + " demos", v == tgn::Variant::Paper});
  }
  for (const auto& f : s.quick ? std::vector<std::string>{"task4", "fetch"} : tasks::allFamilies())
    for (int n : p.sizes) {
      tasks::GeneratorOptions o;
      o.family = f;
      const std::string name = f + "-" + std::to_string(n);
      const fs::path data = dataset(s, name, o, n, s.test);
      for (const auto& v : kVariants)
        p.add(p.few, {data, name + "-" + tgn::toString(v), f, v, std::to_string(n) + " demos", false,
                      v == kDefaultVariant, v == kDefaultVariant});
    }
  for (const auto& f : humanFamilies(s))
    for (int n : p.sizes) {
      tasks::GeneratorOptions o;
      o.family = f;
      o.onset_jitter_s = kHumanOnsetJitter;
      o.jitter_m = kHumanNoise;
      const std::string name = f + "-human-" + std::to_string(n);
      const fs::path data = dataset(s, name, o, n, s.test);
      for (const auto& v : kVariants)
        p.add(p.human, {data, name + "-" + tgn::toString(v), f, v, "human-timed, " + std::to_string(n) + " demos",
                        false, v == kDefaultVariant});
    }
  for (const auto& f : humanFamilies(s)) {
    tasks::GeneratorOptions o;
    o.family = f;
    o.jitter_m = 0.005;
    o.mislabel_fraction = 0.1;
    const std::string name = f + "-imperfect";
    const fs::path data = dataset(s, name, o, s.train, s.test);
    for (const auto& v : kVariants)
      if (v != tgn::Variant::Gnn)
        p.add(p.imperfect,
              {data, name + "-" + tgn::toString(v), f, v, "imperfect, " + std::to_string(s.train) + " demos", false});
  }
}

/// Labels inferred from motion (docs/labels.md): the same demonstrations moved by a person,
/// one labelled by hand, trained on their true labels and on inferred ones, each with
/// label_seeds training seeds: the seed alone moves OSR by more than the goal's 0.02 where
/// few demonstrations leave the network undecided (queue at 10: 0.87-1.00 over 15 seeds on
/// the same data, docs/labels-log.md), so one seed cannot show what the labels change.
void planLabels(const Settings& s, Plan& p) {
  p.label_seeds = s.quick ? 2 : kLabelSeeds;
  for (const auto& f : s.quick ? humanFamilies(s) : tasks::allFamilies())
    for (int n : p.sizes) {
      tasks::GeneratorOptions o;
      o.family = f;
      const std::string name = f + "-motion-" + std::to_string(n);
      const fs::path truth = dataset(s, name, o, n, s.test), inferred = s.out / "data" / (name + "-inferred");
      const label::InferredDataset ds =
          label::inferredDataset(task::loadTaskDir((truth / "train").string()), {}, static_cast<uint64_t>(s.seed));
      task::writeTaskDir(ds.truth, (truth / "train").string());
      task::writeTaskDir(ds.inferred, (inferred / "train").string());
      task::writeTaskDir(task::loadTaskDir((truth / "test").string()), (inferred / "test").string());
      const std::string v = tgn::toString(kDefaultVariant);
      LabelRow row{f, n, ds.score, {}, {}};
      for (int seed = s.seed; seed < s.seed + p.label_seeds; ++seed) {
        const std::string suffix = "-" + v + "-seed" + std::to_string(seed), demos = std::to_string(n) + " demos";
        row.truth_jobs.push_back(p.jobs.size());
        p.add(p.labels,
              {truth, name + "-true" + suffix, f, kDefaultVariant, "true labels, " + demos, false, false, false, seed});
        row.inferred_jobs.push_back(p.jobs.size());
        p.add(p.labels, {inferred, name + "-inferred" + suffix, f, kDefaultVariant, "inferred labels, " + demos, false,
                         false, false, seed});
      }
      p.label_rows.push_back(row);
    }
}

/// The seed of a zoo test set: other scenes than its training set's.
uint64_t zooTestSeed(const Settings& s) {
  return static_cast<uint64_t>(s.seed) * 2654435761ULL + 0x7e57;
}

/// The rule zoo (docs/tgn.md): the default network on a sample of rules, as bench rule_zoo;
/// at the largest size also with bodies, and on the direct motion (rule_zoo.h, ZooMotion;
/// its stop gap cycling over the rules) ideal and with bodies.
void planZoo(const Settings& s, Plan& p) {
  const std::vector<tasks::ZooMotion> direct_motions = tasks::directZooMotions();
  for (uint64_t id : tasks::distinctZooRules(s.zoo_rules)) {
    const tasks::ZooMotion direct = direct_motions[p.zoo_rules.size() % direct_motions.size()];
    p.zoo_rules.push_back(tasks::zooRule(id));
    for (const tasks::ZooMotion& motion : {tasks::ZooMotion{}, direct})
      for (int n : p.sizes) {
        if (motion.direct && n != p.sizes.back()) continue;
        const std::string name =
            "zoo-" + std::to_string(id) + (motion.direct ? "-direct" : "") + "-" + std::to_string(n);
        const fs::path dir = s.out / "data" / name;
        try {
          task::writeTaskDir(tasks::generateZoo(id, n, static_cast<uint64_t>(s.seed), motion),
                             (dir / "train").string());
          task::writeTaskDir(tasks::generateZoo(id, s.test, zooTestSeed(s), motion), (dir / "test").string());
        } catch (const Error&) {
          if (!motion.direct) throw;
          // No scene whose bodies keep clear on straight paths and arcs: not on this motion.
          p.zoo_undrawable += (p.zoo_undrawable.empty() ? "zoo:" : ", zoo:") + std::to_string(id);
          continue;
        }
        Job j{dir, name + "-" + tgn::toString(kDefaultVariant), "zoo:" + std::to_string(id) + motion.suffix(),
              kDefaultVariant, std::to_string(n) + " demos"};
        j.bodies = n == p.sizes.back();
        j.bodies_unfiltered = false;
        p.add(motion.direct ? p.zoo_direct : p.zoo, j);
      }
  }
}

/// The kinds of task users name (rule_zoo.h, userKinds), each its zoo rule, with the zoo.
void planKinds(const Settings& s, Plan& p) {
  if (s.zoo_rules > 0) p.kind_list = tasks::userKinds();
  if (s.quick && p.kind_list.size() > 1) p.kind_list.resize(1);
  for (const tasks::ZooKind& k : p.kind_list) {
    uint64_t id = 0;
    tasks::parseZooFamily(k.family, id);
    for (int n : p.sizes) {
      const std::string name = "kind-" + k.family.substr(4) + "-" + std::to_string(n);
      const fs::path dir = s.out / "data" / name;
      task::writeTaskDir(tasks::generateZoo(id, n, static_cast<uint64_t>(s.seed)), (dir / "train").string());
      task::writeTaskDir(tasks::generateZoo(id, s.test, zooTestSeed(s)), (dir / "test").string());
      p.add(p.kinds, {dir, name + "-" + tgn::toString(kDefaultVariant), k.family, kDefaultVariant,
                      std::to_string(n) + " demos"});
    }
  }
}

/// The data sets (cheap, serial) and every model of the run as one job.
Plan planRun(const Settings& s) {
  Plan p;
  p.sizes = s.quick ? std::vector<int>{3} : std::vector<int>{10, 20};
  planFamilies(s, p);
  planLabels(s, p);
  planZoo(s, p);
  planKinds(s, p);
  return p;
}

/// Fig. 4 and the case studies: plot_loss.py trains (with the same tool and seed) and draws
/// the curves for 10/20/30 demonstrations, 4..11 robots and 2..4 actions; one trajectory
/// overlay per paper task.
void drawFigures(const Settings& s, const fs::path& source) {
  const std::string py = "/usr/bin/python3 '" + (source / "scripts").string() + "/";
  const fs::path figs = s.docs / "figures";
  std::cout << "Fig. 4 and the case studies (training curves, scripts/plot_loss.py)\n" << std::flush;
  runPlot(py + "plot_loss.py' --seed " + std::to_string(s.seed) + " --jobs " + std::to_string(s.jobs) +
          (s.max_epochs > 0 ? " --epochs " + std::to_string(s.max_epochs) : std::string()) + " --work '" +
          (s.out / "loss").string() + "' --out '" + figs.string() + "'");
  for (const auto& f : tasks::paperFamilies())
    runPlot(py + "plot_overlay.py' '" + (s.out / "overlays" / (f + ".csv")).string() + "' --title '" + f + "' --out '" +
            (figs / ("overlay_" + f + ".png")).string() + "'");
}

/// The rows of a run and what they belong to: what every section of the results reads.
struct Run {
  const Settings& s;
  const Plan& p;
  const std::vector<Row>& rows;
  double minutes = 0;  ///< wall time until the results are written
};

std::string methodName(tgn::Variant v) {
  static const std::map<tgn::Variant, std::string> names = {{tgn::Variant::Paper, "DDACE (the paper's network)"},
                                                            {tgn::Variant::Scene, "DDACE, scene network (default)"},
                                                            {tgn::Variant::FullGraph, "w/o spectral clustering"},
                                                            {tgn::Variant::Gnn, "GNN"}};
  return names.at(v);
}
std::string rulesCell(const Row& r) {
  return std::to_string(r.rules[0]) + " / " + std::to_string(r.rules[1]) + " / " + std::to_string(r.rules[2]) + " / " +
         std::to_string(r.rules[3]);
}
std::string metricsCell(const eval::Summary& m) {
  return fmt(m.osr, 2) + " | " + fmt(m.ssr, 2) + " | " + fmt(m.gcr, 2) + " | " + fmt(m.fd, 4);
}
std::string trainingCell(const Row& r) {
  return std::to_string(r.epochs) + " (" + r.stop + ") | " + fmt(r.train_s, 1) + " s";
}
std::string millimetres(double m) {
  return std::isfinite(m) ? fmt(m * 1000, 1) + " mm" : std::string("–");
}
std::string collisionsCell(const eval::Summary& b) {
  return std::to_string(b.collisions) + " (" + std::to_string(b.trials_with_collision) + "/" +
         std::to_string(b.trials) + ")";
}
/// "- what: met/not met. Met: ...; not met: ..." for a goal judged on several rows.
void judged(std::ostream& md, const std::string& what, const std::string& met, const std::string& missed) {
  md << "- " << what << ": " << (missed.empty() ? "**met**" : "**not met**")
     << ". Met: " << (met.empty() ? "none" : met) << (missed.empty() ? "" : "; not met: " + missed) << ".\n";
}
void addTo(std::string& list, const std::string& item) {
  list += (list.empty() ? "" : ", ") + item;
}

void writeHeader(std::ostream& md, const Run& run) {
  const Settings& s = run.s;
  md << "# Results: the paper's Table 2, regenerated, and beyond\n\n"
     << (s.quick ? "**`--quick`: a smoke test of the command (few demonstrations, at most 40 epochs, a few families), "
                   "not the paper's protocol; run `ddace table` for the real numbers.**\n\n"
                 : "")
     << "Written by `ddace table" << (s.quick ? " --quick" : "") << "` (seed " << s.seed
     << "); every number below comes from that run (" << fmt(run.minutes, 1) << " min on this machine, " << s.jobs
     << " models trained at a time). Models and per-trial JSON are in `" << (s.quick ? s.out.string() : "out/table")
     << "`.\n\n"
     << "Each cell: " << s.test << " closed-loop trials on fresh start-goal configurations (ideal path "
     << "following, as the paper), models trained to their loss plateau. OSR, SSR, GCR, FD as defined in "
     << "docs/task-format.md. libtorch's kernels run with `ATEN_CPU_CAPABILITY=" << kCpuCapability
     << "` in every job, so that the numbers do not depend on the host's vector instruction set; OpenBLAS "
     << openBlasKernel()
     << " (OpenBLAS picks its kernels by the processor unless told; they round differently too, so a run "
        "with other kernels can train to other epochs and rows). **E' rules**: how "
        "many of the observed interaction edges each refinement rule "
     << "decided (kept: recurs / kept: same cluster / dropped: rare / dropped: crosses clusters; docs/tgn.md)."
     << (s.gnn_epochs > 0 ? " The GNN baseline was capped at " + std::to_string(s.gnn_epochs) +
                                " epochs (`--gnn-epochs`); the epochs column says whether a model reached its plateau."
                          : std::string())
     << "\n";
}

void writeTable2(std::ostream& md, const Run& run) {
  md << "\n## Table 2: the paper's tasks, " << run.s.train << " demonstrations\n\n"
     << "| task | method | OSR | SSR | GCR | FD | paper (OSR / SSR / GCR / FD) | E' rules | epochs | training |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t i : run.p.table2) {
    const Row& r = run.rows[i];
    md << "| " << r.task << " | " << methodName(r.variant) << " | " << metricsCell(r.m) << " | "
       << paperRow(r.task, tgn::toString(r.variant)) << " | " << rulesCell(r) << " | " << trainingCell(r) << " |\n";
  }
  for (const auto& f : tasks::paperFamilies())
    md << "| " << f << " | LLM (GPT-5.2) | – | – | – | – | " << paperRow(f, "llm")
       << " | | not reproducible offline (needs a hosted LLM) | |\n";
}

/// A section of every method's rows: `which` are indices into the rows.
void writeSection(std::ostream& md, const Run& run, const std::string& title, const std::string& text,
                  const std::vector<size_t>& which) {
  md << "\n## " << title << "\n\n"
     << text << "\n\n"
     << "| family | demonstrations | method | OSR | SSR | GCR | FD | E' rules | epochs | training |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (size_t i : which) {
    const Row& r = run.rows[i];
    md << "| " << r.task << " | " << r.condition << " | " << methodName(r.variant) << " | " << metricsCell(r.m) << " | "
       << rulesCell(r) << " | " << trainingCell(r) << " |\n";
  }
}

void writeFamilySections(std::ostream& md, const Run& run) {
  writeSection(md, run, "Few-shot, every family",
               "The paper's four families (fixed step order) and four where the start configuration decides who acts "
               "and where (docs/task-format.md, \"Task families\"), with few clean demonstrations; test sets are fresh "
               "configurations.",
               run.p.few);
  writeSection(md, run, "Human-timed demonstrations",
               "Training demonstrations labelled as a person does: every token's label begins up to " +
                   fmt(kHumanOnsetJitter, 1) +
                   " s late (step grouping merges it into its step: every token of the step still runs), "
                   "with Gaussian position noise of " +
                   fmt(kHumanNoise * 1000, 0) + " mm on every row; test sets are clean.",
               run.p.human);
  writeSection(md, run, "Imperfect demonstrations",
               "Gaussian position jitter σ = 5 mm on every row, and in 10 % of the demonstrations one motion token's "
               "target mislabelled for its whole segment; test sets are clean. This is where the refinement rules have "
               "edges to drop.",
               run.p.imperfect);
}

void writeLabelsIntro(std::ostream& md, const Run& run) {
  const label::HumanMotionOptions h;
  md << "\n## Labels inferred from motion\n\n"
     << "The training demonstrations moved as a person moves robots by hand (`label::humanMotion`): the robots of a "
        "step start up to "
     << fmt(h.onset_spread_s, 1) << " s apart, each at " << fmt(h.speed_min, 1) << "-" << fmt(h.speed_max, 1)
     << " times the generated speed, " << fmt(h.pause_probability * 100, 0) << " % of them pausing "
     << fmt(h.pause_min_s, 1) << "-" << fmt(h.pause_max_s, 1) << " s on the way, a resting robot bumped "
     << fmt(h.nudge_min_m * 100, 0) << "-" << fmt(h.nudge_max_m * 100, 1) << " cm and put back after "
     << fmt(h.nudge_probability * 100, 0) << " % of the steps, tracked at " << fmt(h.rate_hz, 0) << " Hz with "
     << fmt(h.noise_m * 1000, 1)
     << " mm noise and dropped frames held. The first demonstration is labelled by hand "
        "(the example); the labels of the others are inferred from their motion (`ddace label --example`, "
        "docs/labels.md). **Accuracy**: inferred tokens equal to the true ones (entity, action, target, step) over "
        "the larger of both counts; **exact**: demonstrations whose inferred steps are the true ones; **to check**: "
        "items reported as uncertain; onset and offset errors are medians over matched tokens. OSR: the default "
        "network trained on the true labels, and on the inferred ones, on the same clean test set, once with each "
        "of the training seeds "
     << run.s.seed << "-" << run.s.seed + run.p.label_seeds - 1
     << ": the mean (lowest-highest); **difference**: inferred - true, the mean over the seeds ± its standard "
        "error (of the per-seed differences). The seed alone moves OSR where few demonstrations leave the "
        "network undecided, and so does the row of a step's snapshot, which is all that inferred labels with the "
        "true tokens change for the network (docs/labels-log.md). These demonstrations have no bodies; with "
        "bodies, in each way a person moves one at a time and all together, on the zoo's kinds of task and a "
        "sample of its rules in both of its ways of moving, with how far the tokens listed to check can be "
        "trusted: docs/bench/label_styles.md (`ddace bench label_styles`).\n\n"
     << "| family | demonstrations | accuracy | exact | to check | onset error | offset error | OSR, true labels | "
        "OSR, inferred labels | difference |\n|---|---|---|---|---|---|---|---|---|---|\n";
}

/// OSR over the training seeds of `js`: "mean (lowest-highest)".
std::string osrOverSeeds(const Run& run, const std::vector<size_t>& js) {
  double sum = 0, lo = 1, hi = 0;
  for (size_t j : js) {
    const double osr = run.rows[j].m.osr;
    sum += osr, lo = std::min(lo, osr), hi = std::max(hi, osr);
  }
  return fmt(sum / static_cast<double>(js.size()), 2) + " (" + fmt(lo, 2) + "-" + fmt(hi, 2) + ")";
}

void writeLabels(std::ostream& md, const Run& run) {
  writeLabelsIntro(md, run);
  double worst_accuracy = 1, worst_onset = 0, worst_offset = 0, worst_gap = 0, worst_gap_se = 0;
  std::string worst_gap_row;
  for (const auto& lr : run.p.label_rows) {
    const double on = label::median(lr.score.onset_error_s), off = label::median(lr.score.offset_error_s);
    std::vector<double> diff;  // per seed: inferred - true
    for (size_t k = 0; k < lr.truth_jobs.size(); ++k)
      diff.push_back(run.rows[lr.inferred_jobs[k]].m.osr - run.rows[lr.truth_jobs[k]].m.osr);
    double mean = 0, var = 0;
    for (double d : diff) mean += d / static_cast<double>(diff.size());
    for (double d : diff) var += (d - mean) * (d - mean) / std::max<double>(1, static_cast<double>(diff.size()) - 1);
    const double se = std::sqrt(var / static_cast<double>(diff.size()));
    worst_accuracy = std::min(worst_accuracy, lr.score.accuracy());
    worst_onset = std::max(worst_onset, on);
    worst_offset = std::max(worst_offset, off);
    if (std::abs(mean) > worst_gap) {
      worst_gap = std::abs(mean), worst_gap_se = se;
      worst_gap_row = lr.family + " at " + std::to_string(lr.demos);
    }
    md << "| " << lr.family << " | " << lr.demos << " | " << fmt(lr.score.accuracy(), 3) << " | "
       << lr.score.demos_exact << "/" << lr.score.demos << " | " << lr.score.notes << " | " << fmt(on, 3) << " s | "
       << fmt(off, 3) << " s | " << osrOverSeeds(run, lr.truth_jobs) << " | " << osrOverSeeds(run, lr.inferred_jobs)
       << " | " << (mean < -0.005 ? "-" : "+") << fmt(std::abs(mean), 2) << " ± " << fmt(se, 2) << " |\n";
  }
  md << "\nGoals (labels inferred from motion): token accuracy >= 0.98 on every family: "
     << (worst_accuracy >= 0.98 ? "**met**" : "**not met**") << " (lowest " << fmt(worst_accuracy, 3)
     << "); median onset and offset error < 0.2 s: "
     << (worst_onset < 0.2 && worst_offset < 0.2 ? "**met**" : "**not met**") << " (largest " << fmt(worst_onset, 3)
     << " s, " << fmt(worst_offset, 3) << " s); OSR on inferred labels within 0.02 of OSR on true labels: "
     << (worst_gap <= 0.02 + 1e-9 ? "**met**" : "**not met**") << " (largest difference of the means "
     << fmt(worst_gap, 2)
     << (worst_gap_row.empty() ? std::string() : ", " + worst_gap_row + ", standard error " + fmt(worst_gap_se, 2))
     << ").\n";
}

/// The row of zoo rule k at sizes[m].
const Row& zooRow(const Run& run, size_t k, size_t m) {
  return run.rows[run.p.zoo[k * run.p.sizes.size() + m]];
}

void writeZoo(std::ostream& md, const Run& run) {
  const Plan& p = run.p;
  md << "\n## Rule zoo\n\n"
     << "The default network on the first " << p.zoo_rules.size()
     << " distinct rules of the rule zoo (rules people state about a table, docs/tgn.md; `--zoo-rules N`), "
     << run.s.test << " fresh scenes each, ideal execution; the distribution of OSR over the rules "
     << "(`ddace bench rule_zoo` measures the same with its own sample size: docs/bench/rule_zoo.md).\n\n"
     << "| demonstrations | rules | median OSR | 10th percentile | mean | rules at OSR >= 0.9 | worst |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (size_t m = 0; m < p.sizes.size(); ++m) {
    std::vector<double> v;
    for (size_t k = 0; k < p.zoo_rules.size(); ++k) v.push_back(zooRow(run, k, m).m.osr);
    size_t worst = 0;
    for (size_t k = 1; k < v.size(); ++k)
      if (v[k] < v[worst]) worst = k;
    const tasks::OsrDistribution d = tasks::osrDistribution(v);
    md << "| " << p.sizes[m] << " | " << d.rules << " | " << fmt(d.median, 2) << " | " << fmt(d.p10, 2) << " | "
       << fmt(d.mean, 2) << " | " << d.at_least_0_9 << " | zoo:" << p.zoo_rules[worst].id << " "
       << p.zoo_rules[worst].name << " (" << fmt(v[worst], 2) << ") |\n";
  }
}

/// With bodies: rule k's rows at the largest size, the generators' motion and the direct one.
void writeZooBodies(std::ostream& md, const Run& run) {
  const Plan& p = run.p;
  md << "\n### Rule zoo with bodies\n\n"
     << "The same rules at " << p.sizes.back()
     << " demonstrations on two motion models (rule_zoo.h, `ZooMotion`): the generators' (paths bent around "
        "bodies, stops touching) and a direct one (paths straight or arcs bent around nothing, stops touching, "
        "4 mm and 1 cm short of contact in turn over the rules), each trained on its own demonstrations, ideal and "
        "with bodies as in \"Bodies\" below (the filter on). Ratios per rule, bodies over ideal. Goals: OSR ratio >= "
     << tasks::kBodiesOsrRatioMedian << " at the median and >= " << tasks::kBodiesOsrRatioP10
     << " at the 10th percentile, zero collisions, FD ratio <= " << tasks::kBodiesFdRatioMedian
     << " at the median (`ddace bench rule_zoo` lists every rule).\n\n"
     << "| motion | rules | median OSR ideal / bodies | OSR ratio median | p10 | collisions (trials) | min clearance "
        "| FD ratio median | makespan, mean | goals |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const bool direct : {false, true}) {
    std::vector<std::pair<eval::Summary, eval::Summary>> runs;
    if (direct)
      for (size_t i : p.zoo_direct) runs.push_back({run.rows[i].m, run.rows[i].bodies});
    else
      for (size_t k = 0; k < p.zoo_rules.size(); ++k) {
        const Row& r = zooRow(run, k, p.sizes.size() - 1);
        runs.push_back({r.m, r.bodies});
      }
    if (runs.empty()) continue;
    const tasks::BodiesComparison c = tasks::compareBodies(runs);
    md << "| " << (direct ? "direct (touching, 4 mm, 1 cm)" : "the generators'") << " | " << c.rules << " | "
       << fmt(c.ideal_osr_median, 2) << " / " << fmt(c.bodies_osr_median, 2) << " | " << fmt(c.osr_ratio_median, 2)
       << " | " << fmt(c.osr_ratio_p10, 2) << " | " << c.collisions << " (" << c.trials_with_collision << "/"
       << c.trials << ") | " << millimetres(c.min_clearance_m) << " | " << fmt(c.fd_ratio_median, 2) << " | "
       << fmt(c.makespan_s, 1) << " s | " << (c.goalsMet() ? "met" : "**not met**") << " |\n";
  }
  md << "\nRules the direct motion cannot demonstrate (no scene whose bodies keep clear without bending around "
        "each other), not in its row: "
     << (p.zoo_undrawable.empty() ? std::string("none") : p.zoo_undrawable) << ".\n";
}

/// OSR of each zoo rule's model at the largest size on scenes with `factor` times its robots
/// (goals too where the rule has one per robot or more). Counts the refused and the undrawable.
std::vector<double> otherTeamSizeOsr(const Run& run, double factor, int& refused, int& no_scene) {
  const Plan& p = run.p;
  std::vector<double> v;
  for (size_t k = 0; k < p.zoo_rules.size(); ++k) {
    const tasks::ZooRule& z = p.zoo_rules[k];
    tasks::ZooCounts c;
    c.robots = std::max(1, static_cast<int>(std::lround(factor * z.robots)));
    c.goals = z.goals >= z.robots ? c.robots + z.goals - z.robots : z.goals;
    const std::string model_dir =
        (run.s.out / "models" / p.jobs[p.zoo[(k + 1) * p.sizes.size() - 1]].model_name).string();
    task::TaskDir test;
    try {
      test = tasks::generateZoo(z.id, run.s.test, zooTestSeed(run.s), {}, c);
    } catch (const Error&) {
      ++no_scene;
      continue;
    }
    try {
      const ModelForTask bound = modelForTask(loadModel(model_dir), model_dir, test, "other", false);
      v.push_back(evaluate(bound.model, test, {}).summary.osr);
    } catch (const Error&) {
      ++refused;
    }
  }
  return v;
}

/// Median FD (ideal) of the zoo models `jobs` on their own test sets: with the paths as
/// fitting keyed them (by role where that predicts better, docs/gp.md "Roles") and from the
/// names' primitives. Rules whose FD is not finite either way are left out.
std::pair<double, double> zooFdAsFittedAndByName(const Run& run, const std::vector<size_t>& jobs, size_t& rules) {
  std::vector<double> fitted, by_name;
  EvalOptions names;
  names.paths_by_name = true;
  for (size_t i : jobs) {
    const Job& j = run.p.jobs[i];
    try {
      const double fd = evaluate(loadModel((run.s.out / "models" / j.model_name).string()),
                                 task::loadTaskDir((j.data / "test").string()), names)
                            .summary.fd;
      if (!std::isfinite(fd) || !std::isfinite(run.rows[i].m.fd)) continue;
      fitted.push_back(run.rows[i].m.fd);
      by_name.push_back(fd);
    } catch (const Error&) {
      continue;  // a job that failed has no model: its row says so
    }
  }
  rules = fitted.size();
  if (fitted.empty()) return {NAN, NAN};
  return {tasks::osrDistribution(fitted).median, tasks::osrDistribution(by_name).median};
}

/// Other team sizes (docs/tgn.md): each rule's model at the largest size run on the same
/// rule with other numbers of robots.
void writeOtherTeamSizes(std::ostream& md, const Run& run) {
  md << "\n### Other team sizes\n\n"
     << "Each rule's model of " << run.p.sizes.back()
     << " demonstrations (the default network, at the rule's own counts) on " << run.s.test
     << " fresh scenes of the same rule with other numbers of robots (and of goals where the rule has one per robot "
        "or more: the surplus kept), bound by kind as `ddace eval` binds it (docs/tgn.md, \"Other team sizes\"), "
        "ideal execution. Refused: models whose rule depends on names (a fixed order, an entity known by name that "
        "the other count lacks or adds); no scene: the rule cannot be stated at that count.\n\n"
     << "| robots | rules run | refused | no scene | median OSR | 10th percentile | rules at OSR >= 0.9 |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const double factor : {0.5, 1.5, 2.0}) {
    int refused = 0, no_scene = 0;
    const std::vector<double> v = otherTeamSizeOsr(run, factor, refused, no_scene);
    md << "| " << fmt(factor, 1) << "x | " << v.size() << " | " << refused << " | " << no_scene << " | ";
    if (v.empty()) {
      md << "– | – | – |\n";
      continue;
    }
    const tasks::OsrDistribution d = tasks::osrDistribution(v);
    md << fmt(d.median, 2) << " | " << fmt(d.p10, 2) << " | " << d.at_least_0_9 << " |\n";
  }
  md << "\nMotion primitives by role (docs/gp.md, \"Roles\"): the FD of the same models at the rules' own counts "
        "(ideal execution), their paths as fitting keyed each motion class (by the step its motions stand in where "
        "that predicts held-out motions better than the names) and every path from its names' primitive (the "
        "paper's keys; `EvalOptions::paths_by_name`). Median over the rules.\n\n"
     << "| motion | rules | FD, as fitted | FD, by name | by name / as fitted |\n|---|---|---|---|---|\n";
  std::vector<size_t> largest;
  for (size_t k = 0; k < run.p.zoo_rules.size(); ++k) largest.push_back(run.p.zoo[(k + 1) * run.p.sizes.size() - 1]);
  const std::vector<std::pair<std::string, std::vector<size_t>>> motions = {{"the generators'", largest},
                                                                            {"direct", run.p.zoo_direct}};
  for (const auto& [motion, jobs] : motions) {
    size_t rules = 0;
    const auto [fitted, by_name] = zooFdAsFittedAndByName(run, jobs, rules);
    md << "| " << motion << " | " << rules << " | " << fmt(fitted, 4) << " | " << fmt(by_name, 4) << " | "
       << fmt(by_name / fitted, 2) << " |\n";
  }
}

void writeKinds(std::ostream& md, const Run& run) {
  const Plan& p = run.p;
  md << "\n### Kinds of task users name\n\n"
     << "Each kind as the zoo rule that states it (rule_zoo.h, `userKinds`; goal: OSR >= 0.9 at 20 "
        "demonstrations), "
     << run.s.test << " fresh scenes each, ideal execution.\n\n| kind | zoo rule |";
  for (int n : p.sizes) md << " OSR, " << n << " demos |";
  md << "\n|---|---|";
  for (size_t m = 0; m < p.sizes.size(); ++m) md << "---|";
  md << "\n";
  for (size_t k = 0; k < p.kind_list.size(); ++k) {
    uint64_t id = 0;
    tasks::parseZooFamily(p.kind_list[k].family, id);
    md << "| " << p.kind_list[k].kind << " | " << p.kind_list[k].family << " " << tasks::zooRule(id).name << " |";
    for (size_t m = 0; m < p.sizes.size(); ++m)
      md << " " << fmt(run.rows[p.kinds[k * p.sizes.size() + m]].m.osr, 2) << " |";
    md << "\n";
  }
}

/// The default network's models of the sections above, run again in closed loop.
void writeClosedLoop(std::ostream& md, const Run& run) {
  md << "\n## Closed loop: simulated differential-drive robots\n\n"
     << "The default network's models of \"Few-shot, every family\" and \"Human-timed demonstrations\", on the same "
        "test configurations, executed by differential-drive robots (Hamster wheel base, wheel speeds clamped) steered "
        "along "
        "their planned paths by the control law of the path follower node, from positions measured with "
     << fmt(kClosedLoopNoise * 1000, 0)
     << " mm Gaussian noise: a robot stops within the arrival radius, not on its target, and the next decision sees "
        "where it stopped (`ddace eval --execution diffdrive --noise "
     << kClosedLoopNoise << "`). Ideal: the rows above.\n\n"
     << "| family | demonstrations | ideal OSR | SSR | GCR | FD | closed-loop OSR | SSR | GCR | FD |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto* which : {&run.p.few, &run.p.human})
    for (size_t i : *which) {
      const Row& r = run.rows[i];
      if (r.closed.trials == 0) continue;
      md << "| " << r.task << " | " << r.condition << " | " << metricsCell(r.m) << " | " << metricsCell(r.closed)
         << " |\n";
    }
}

void writeBodiesIntro(std::ostream& md) {
  md << "\n## Bodies\n\n"
     << "The default network's models of \"Few-shot, every family\" on the same test configurations, executed with "
        "bodies: every robot and object a disc of the task's footprint on the mock robots' Box2D table, the robots of "
        "a step driving at the same time, each steered by the path follower's control law from positions measured "
        "with "
     << fmt(kClosedLoopNoise * 1000, 0)
     << " mm noise, its command through its own safety filter fed with the others' poses; a load riding in front "
        "of its carrier (part of the carrier's body for its filter), other objects carried along their own paths, and "
        "pushed when something drives into them (`ddace eval --execution diffdrive --noise "
     << kClosedLoopNoise
     << "`; without the filter: `--no-filter`). **Collisions**: contacts that began between two bodies apart, "
        "except a motion and its own target, a carrier and its load, and a motion and a body its end point touches "
        "(in how many trials); a trial with a collision is no success. **Min clearance**: the smallest gap between two "
        "bodies that keep apart, over every trial. "
        "**Makespan**: simulated time of a trial's steps, mean over the trials. Ideal OSR: the row of \"Few-shot, "
        "every family\".\n\n"
     << "| family | demonstrations | ideal OSR | OSR with bodies | GCR | collisions | min clearance | makespan | "
        "OSR without filter | collisions | min clearance | makespan | makespan with / without |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
}

/// The few-shot default-network models again, the robots with bodies, and the goals of bodies.
void writeBodies(std::ostream& md, const Run& run) {
  writeBodiesIntro(md);
  std::string no_collision, collided, osr_met, osr_missed, time_met, time_missed;
  for (size_t i : run.p.few) {
    const Row& r = run.rows[i];
    if (r.bodies.trials == 0) continue;
    const double ratio = r.unfiltered.makespan_s > 0 ? r.bodies.makespan_s / r.unfiltered.makespan_s : NAN;
    md << "| " << r.task << " | " << r.condition << " | " << fmt(r.m.osr, 2) << " | " << fmt(r.bodies.osr, 2) << " | "
       << fmt(r.bodies.gcr, 2) << " | " << collisionsCell(r.bodies) << " | " << millimetres(r.bodies.min_clearance_m)
       << " | " << fmt(r.bodies.makespan_s, 1) << " s | " << fmt(r.unfiltered.osr, 2) << " | "
       << collisionsCell(r.unfiltered) << " | " << millimetres(r.unfiltered.min_clearance_m) << " | "
       << fmt(r.unfiltered.makespan_s, 1) << " s | " << fmt(ratio, 2) << " |\n";
    const std::string name = r.task + " (" + r.condition + ")";
    addTo(r.bodies.collisions == 0 ? no_collision : collided, name);
    addTo(r.bodies.osr >= 0.95 * r.m.osr - 1e-9 ? osr_met : osr_missed,
          name + " " + fmt(r.bodies.osr, 2) + " vs " + fmt(r.m.osr, 2));
    addTo(ratio <= 1.15 + 1e-9 ? time_met : time_missed, name + " " + fmt(ratio, 2));
  }
  md << "\nGoals of the bodies, with the filter:\n\n";
  judged(md, "Zero collisions on every family", no_collision, collided);
  judged(md, "OSR with bodies >= 0.95 x the ideal OSR", osr_met, osr_missed);
  judged(md, "Makespan with the filter <= 1.15 x without", time_met, time_missed);
}

void writeFigures(std::ostream& md) {
  md << "\n## Figures\n\n"
     << "Training loss vs epoch for 10, 20 and 30 demonstrations (Fig. 4):\n\n"
     << "![Fig. 4](figures/loss_fig4.png)\n\n"
     << "Case study 1, team size on Task 2 (log loss):\n\n![team size](figures/loss_task2_robots.png)\n\n"
     << "Case study 2, number of actions on Task 3:\n\n![actions](figures/loss_task3_actions.png)\n\n"
     << "Demonstrated (grey) and generated (colour) paths of the first test trial of each task:\n\n";
  for (const auto& f : tasks::paperFamilies()) md << "![" << f << "](figures/overlay_" << f << ".png)\n";
}

/// An accuracy goal judged on the default network's rows of `section` for `families` under
/// `condition` (nothing when the run has no such rows: --quick).
void writeGoal(std::ostream& md, const Run& run, const std::string& what, const std::vector<size_t>& section,
               const std::vector<std::string>& families, const std::string& condition, double bound,
               bool every_metric) {
  std::string met, missed;
  for (size_t i : section) {
    const Row& r = run.rows[i];
    if (r.variant != kDefaultVariant || r.condition != condition ||
        std::find(families.begin(), families.end(), r.task) == families.end())
      continue;
    const bool ok = r.m.osr >= bound && (!every_metric || (r.m.ssr >= bound && r.m.gcr >= bound));
    addTo(ok ? met : missed, r.task + " (OSR " + fmt(r.m.osr, 2) + ")");
  }
  if (!met.empty() || !missed.empty()) judged(md, what, met, missed);
}

/// The accuracy goals, judged on this run's rows of the default network.
void writeGoals(std::ostream& md, const Run& run) {
  if (run.s.quick) return;  // --quick has no such rows
  const std::vector<std::string> scene = tasks::sceneFamilies(), paper = tasks::paperFamilies();
  md << "\n## Goals (the default network, this run)\n\n";
  writeGoal(md, run, "Scene-dependent families, OSR >= 0.9 with 20 demonstrations", run.p.few, scene, "20 demos", 0.9,
            false);
  writeGoal(md, run, "Stretch: scene-dependent families, OSR >= 0.9 with 10 demonstrations", run.p.few, scene,
            "10 demos", 0.9, false);
  writeGoal(md, run,
            "Human-timed demonstrations (onset jitter " + fmt(kHumanOnsetJitter, 1) + " s, " +
                fmt(kHumanNoise * 1000, 0) + " mm), OSR >= 0.95 with 20 demonstrations on every fixed-order family",
            run.p.human, paper, "human-timed, 20 demos", 0.95, false);
  writeGoal(md, run, "The paper's Tasks 1-4, OSR = SSR = GCR = 1 with 10 demonstrations", run.p.few, paper, "10 demos",
            1.0, true);
}

/// docs/results.md: every section, from this run's rows.
std::string resultsText(const Run& run) {
  std::ostringstream md;
  writeHeader(md, run);
  writeTable2(md, run);
  writeFamilySections(md, run);
  writeLabels(md, run);
  if (!run.p.zoo_rules.empty()) {
    writeZoo(md, run);
    writeZooBodies(md, run);
    writeOtherTeamSizes(md, run);
  }
  if (!run.p.kind_list.empty()) writeKinds(md, run);
  writeClosedLoop(md, run);
  writeBodies(md, run);
  writeFigures(md);
  writeGoals(md, run);
  md << "\n## Reading the numbers\n\n" << DDACE_RESULTS_DISCUSSION;
  return md.str();
}

/// The 20-minute goal is a benchmark: the run's wall time goes next to the other benches.
void writeBenchTable(const Run& run) {
  const Settings& s = run.s;
  fs::create_directories(s.docs / "bench");
  std::ofstream(s.docs / "bench" / "table.md")
      << "# bench: table\n\nWritten by `ddace table" << (s.quick ? " --quick" : "") << "` on " << hardwareCores()
      << " cores, " << s.jobs << " models at a time (1-minute load average " << loadAverage()
      << " at the end). The whole command: data, " << run.rows.size()
      << " models trained and evaluated, the training curves (scripts/plot_loss.py), the figures.\n\n"
      << "| measure | time | goal | ratio |\n|---|---|---|---|\n"
      << "| `ddace table" << (s.quick ? " --quick" : "") << "` wall time | " << fmt(run.minutes, 1) << " min | "
      << (s.quick ? "(smoke test, no goal)" : "20 min") << " | "
      << (s.quick ? "–" : fmt(run.minutes / 20, 2) + " of the goal") << " |\n";
}

int runTable(const std::vector<std::string>& argv) {
  Args args(argv, {"--out", "--docs", "--seed", "--gnn-epochs", "--jobs", "--repo", "--zoo-rules"}, {"--quick"});
  ::setenv("ATEN_CPU_CAPABILITY", kCpuCapability, 1);  // before any job touches libtorch
  args.expectAtMostPositional(0);
  // The repository found at run time (--repo DIR, DDACE_REPO, the directories above): its
  // docs/ get the results, scripts/plot_loss.py draws Fig. 4.
  const fs::path source = findRepository(args.get("--repo", ""), {"scripts/plot_loss.py", "docs"});
  const Settings s = parseSettings(args, source);
  for (const char* sub : {"data", "models", "eval", "overlays"}) fs::create_directories(s.out / sub);
  fs::create_directories(s.docs / "figures");
  const auto t_all = Clock::now();
  std::cout << "Table 2 (tasks 1-4, " << s.train << " demonstrations) and beyond: every family with "
            << (s.quick ? "3" : "10 and 20") << " demonstrations, human-timed demonstrations (onset jitter "
            << kHumanOnsetJitter << " s, " << kHumanNoise * 1000 << " mm noise), imperfect demonstrations; " << s.test
            << " trials each; " << s.jobs << " models trained at a time\n";
  const Plan plan = planRun(s);
  const std::vector<Row> rows = runJobs(s, plan.jobs);
  drawFigures(s, source);
  Run run{s, plan, rows, secondsSince(t_all) / 60};
  const fs::path results = s.docs / "results.md";
  writeTextFile(results.string(), resultsText(run));
  run.minutes = secondsSince(t_all) / 60;
  writeBenchTable(run);
  std::cout << "wrote " << results.string() << ", " << (s.docs / "bench" / "table.md").string() << " and "
            << (s.docs / "figures").string() << "/*.png (" << fmt(run.minutes, 1) << " min)\n";
  if (plot_failures) std::cerr << "ddace table: " << plot_failures << " figure(s) could not be drawn (see above)\n";
  return plot_failures ? 1 : 0;
}

}  // namespace

DDACE_COMMAND(
    {"table",
     "ddace table [--out DIR] [--docs DIR] [--quick] [--seed S] [--gnn-epochs N] [--jobs N] [--zoo-rules N=50] "
     "[--repo DIR]",
     "regenerate the paper's Table 2, Fig. 4, the case studies and trajectory overlays into "
     "docs/results.md and docs/bench/table.md (--quick: a smoke test of a few minutes, written to "
     "out/table-quick)",
     runTable});

}  // namespace ddace::cli
