// bench_gp_fit: fitting and predicting one motion primitive, against scikit-learn in the
// same run.
//
// Data: the spiral primitive R3:move:G1 of a generated Task 4 (seed 1), its first 5, 10
// and 20 demonstrations, each segment resampled to 100 progress values (500, 1000, 2000
// samples per axis). Both sides fit an x-GP and a y-GP with C*RBF + White, the same
// initial values, bounds, alpha and 2 restarts, starting from the raw samples.
// scikit-learn (bench/gp_fit_reference.py, /usr/bin/python3) runs at 500 samples by
// default; --sklearn-demos 5,10,20 asks for more (minutes).
//
// Writes docs/bench/gp_fit.md under the repository (--repo DIR or found: common/repository.h).
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <thread>

#include <yaml-cpp/yaml.h>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/gp/primitives.h"
#include "ddace/tasks/generators.h"
#include "results.h"

namespace fs = std::filesystem;
using namespace ddace;

namespace {

const char* kKey = "R3:move:G1";

struct Set {
  int demos = 0;
  Eigen::VectorXd x, y_x, y_y;  // raw samples: progress, canonical x, canonical y
};

/// Wall-clock and CPU time (of this process) in milliseconds. On a shared machine the CPU
/// time is the work done; the wall time also counts waiting for a core.
struct Timing {
  double wall_ms = 0, cpu_ms = 0;
};

struct Ours {
  Timing fit;
  double lml_x = 0, lml_y = 0;
  int evaluations = 0;
};

double cpuMs() {
  return processCpuS() * 1e3;
}

/// Medians over repeated runs (at least `min_runs` and `min_total_ms` of wall time).
template <typename F>
Timing median(F&& f, int min_runs, double min_total_ms) {
  std::vector<double> wall, cpu;
  double total = 0;
  while (static_cast<int>(wall.size()) < min_runs || total < min_total_ms) {
    const auto t0 = SteadyClock::now();
    const double c0 = cpuMs();
    f();
    cpu.push_back(cpuMs() - c0);
    wall.push_back(msSince(t0));
    total += wall.back();
    if (wall.size() > 100000) break;
  }
  std::sort(wall.begin(), wall.end());
  std::sort(cpu.begin(), cpu.end());
  return {wall[wall.size() / 2], cpu[cpu.size() / 2]};
}

std::string jsonArray(const Eigen::VectorXd& v) {
  std::ostringstream s;
  s << std::setprecision(17) << "[";
  for (Eigen::Index i = 0; i < v.size(); ++i) s << (i ? "," : "") << v[i];
  s << "]";
  return s.str();
}

/// The demonstration counts --sklearn-demos asks scikit-learn to fit (default 5); nothing
/// when the arguments are not understood.
std::optional<std::vector<int>> sklearnDemos(int argc, char** argv) {
  std::vector<int> demos = {5};
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) != "--sklearn-demos" || i + 1 >= argc) return std::nullopt;
    demos.clear();
    std::stringstream ss(argv[++i]);
    for (std::string part; std::getline(ss, part, ',');) {
      if (part != "5" && part != "10" && part != "20")
        throw Error("--sklearn-demos takes a comma-separated subset of 5,10,20, got '" + part + "'");
      demos.push_back(std::stoi(part));
    }
  }
  return demos;
}

/// The raw samples of kKey in the first 5, 10 and 20 demonstrations of `all`.
std::vector<Set> sampleSets(const task::TaskDir& all, const gp::PrimitiveOptions& popt) {
  std::vector<Set> sets;
  for (int demos : {5, 10, 20}) {
    task::TaskDir sub = all;
    sub.demos.resize(demos);
    const auto segs = gp::canonicalSegments(sub, popt).at(kKey).canonical;
    Set s;
    s.demos = demos;
    const Eigen::Index n = static_cast<Eigen::Index>(segs.size()) * popt.points;
    s.x.resize(n);
    s.y_x.resize(n);
    s.y_y.resize(n);
    Eigen::Index k = 0;
    for (const auto& path : segs)
      for (int i = 0; i < popt.points; ++i, ++k) {
        s.x[k] = static_cast<double>(i) / (popt.points - 1);
        s.y_x[k] = path[i].x();
        s.y_y[k] = path[i].y();
      }
    sets.push_back(std::move(s));
  }
  return sets;
}

/// Our fit of every set: its median time, likelihood and evaluations.
std::vector<Ours> fitOurs(const std::vector<Set>& sets, const gp::GpOptions& gopt) {
  std::vector<Ours> ours;
  for (const auto& s : sets) {
    Ours o;
    gp::GaussianProcess gx, gy;
    o.fit = median(
        [&] {
          gx = gp::GaussianProcess::fit(s.x, s.y_x, gopt);
          gy = gp::GaussianProcess::fit(s.x, s.y_y, gopt);
        },
        5, 1000);
    o.lml_x = gx.logMarginalLikelihood();
    o.lml_y = gy.logMarginalLikelihood();
    o.evaluations = gx.evaluations() + gy.evaluations();
    ours.push_back(o);
    std::cerr << "ours " << s.x.size() << " samples: fit " << o.fit.wall_ms << " ms (CPU " << o.fit.cpu_ms << " ms)\n";
  }
  return ours;
}

/// Prediction at 100 progress values: mean and std of one GP (no cache involved), and a
/// whole retargeted primitive path from the library (both GPs), on the cached grid and off it.
struct Predictions {
  Timing one_gp, path_cached, path_evaluated;
};

Predictions timePredictions(const task::TaskDir& all, const Set& set, const gp::GpOptions& gopt) {
  Predictions p;
  const gp::GaussianProcess gx = gp::GaussianProcess::fit(set.x, set.y_x, gopt);
  const Eigen::VectorXd xq = Eigen::VectorXd::LinSpaced(100, 0.0, 1.0);
  Eigen::VectorXd mean, sd;
  p.one_gp = median([&] { gx.predict(xq, mean, &sd); }, 200, 300);
  task::TaskDir train5 = all;
  train5.demos.resize(5);
  const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(train5);
  p.path_cached = median([&] { (void)lib.generate(std::string(kKey), {0.2, 0.3}, {0.8, 0.6}, 100); }, 200, 300);
  p.path_evaluated = median([&] { (void)lib.generate(std::string(kKey), {0.2, 0.3}, {0.8, 0.6}, 101); }, 200, 300);
  return p;
}

/// scikit-learn's fit of the sets of `demos` with the same kernel and options, and its
/// prediction, in the same run (bench/gp_fit_reference.py): its JSON output.
YAML::Node runSklearn(const fs::path& repo, const std::vector<Set>& sets, const std::vector<int>& demos,
                      const gp::GpOptions& gopt) {
  const fs::path tmp = fs::temp_directory_path() / ("ddace_bench_gp_fit_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  std::ostringstream in;
  in << std::setprecision(17) << "{\"predict_points\": 100, \"kernel\": {"
     << "\"constant\": " << gopt.initial.constant << ", \"length_scale\": " << gopt.initial.length_scale
     << ", \"noise_level\": " << gopt.initial.noise_level << ", \"constant_bounds\": [" << gopt.constant_bounds.lower
     << ", " << gopt.constant_bounds.upper << "], \"length_scale_bounds\": [" << gopt.length_scale_bounds.lower << ", "
     << gopt.length_scale_bounds.upper << "], \"noise_bounds\": [" << gopt.noise_bounds.lower << ", "
     << gopt.noise_bounds.upper << "], \"restarts\": " << gopt.restarts << ", \"alpha\": " << gopt.alpha
     << "}, \"sets\": [";
  bool first = true;
  for (const auto& s : sets) {
    if (std::find(demos.begin(), demos.end(), s.demos) == demos.end()) continue;
    in << (first ? "" : ",") << "{\"name\": \"" << s.demos << "\", \"x\": " << jsonArray(s.x)
       << ", \"y_x\": " << jsonArray(s.y_x) << ", \"y_y\": " << jsonArray(s.y_y) << "}";
    first = false;
  }
  in << "]}\n";
  writeTextFile((tmp / "in.json").string(), in.str());
  const std::string cmd = "/usr/bin/python3 '" + (repo / "bench" / "gp_fit_reference.py").string() + "' '" +
                          (tmp / "in.json").string() + "' '" + (tmp / "out.json").string() + "'";
  if (std::system(cmd.c_str()) != 0) throw Error("the scikit-learn reference failed: " + cmd);
  const YAML::Node ref = YAML::Load(readTextFile((tmp / "out.json").string()));
  fs::remove_all(tmp);
  return ref;
}

/// scikit-learn's result for `set`, or an undefined node when it did not fit that set.
YAML::Node sklearnSet(const YAML::Node& ref, const Set& set) {
  const YAML::Node ref_sets = ref["sets"];
  for (size_t j = 0; j < ref_sets.size(); ++j)
    if (ref_sets[j]["name"].as<std::string>() == std::to_string(set.demos)) return ref_sets[j];
  return YAML::Node(YAML::NodeType::Undefined);
}

/// The fit table's rows: ours against scikit-learn's where it ran. Also returns
/// scikit-learn's prediction times (-1 when it fitted nothing).
std::string fitRows(const std::vector<Set>& sets, const std::vector<Ours>& ours, const YAML::Node& ref,
                    double& sk_predict_ms, double& sk_predict_cpu_ms) {
  std::ostringstream md;
  md << std::fixed;
  sk_predict_ms = sk_predict_cpu_ms = -1;
  for (size_t i = 0; i < sets.size(); ++i) {
    const Ours& o = ours[i];
    md << "| " << sets[i].demos << " | " << sets[i].x.size() << " | " << std::setprecision(2) << o.fit.wall_ms << " | "
       << o.fit.cpu_ms << " | ";
    const YAML::Node r = sklearnSet(ref, sets[i]);
    if (!r.IsDefined()) {
      md << "not run | | | | " << std::setprecision(3) << o.lml_x + o.lml_y << " | |\n";
      continue;
    }
    const double sk_s = r["fit_s"].as<double>(), sk_cpu_s = r["fit_cpu_s"].as<double>();
    const double sk_lml = r["lml_x"].as<double>() + r["lml_y"].as<double>();
    sk_predict_ms = r["predict_ms"].as<double>();
    sk_predict_cpu_ms = r["predict_cpu_ms"].as<double>();
    md << std::setprecision(2) << sk_s << " | " << sk_cpu_s << " | " << std::setprecision(0)
       << sk_s * 1000 / o.fit.wall_ms << "x | " << sk_cpu_s * 1000 / o.fit.cpu_ms << "x | " << std::setprecision(3)
       << o.lml_x + o.lml_y << " | " << sk_lml << " |\n";
  }
  return md.str();
}

/// docs/bench/gp_fit.md.
std::string report(const std::vector<Set>& sets, const std::vector<Ours>& ours, const Predictions& predict,
                   const YAML::Node& ref, const gp::PrimitiveOptions& popt, const std::string& load) {
  const gp::GpOptions& gopt = popt.gp;
  double sk_predict_ms = -1, sk_predict_cpu_ms = -1;
  const std::string fit_rows = fitRows(sets, ours, ref, sk_predict_ms, sk_predict_cpu_ms);
  std::ostringstream md;
  md << std::fixed;
  md << "# GP primitive fit and prediction vs scikit-learn\n\n"
     << "Written by `bench_gp_fit` (bench/gp_fit.cpp; `ddace bench gp_fit`). Do not edit.\n\n"
     << "Primitive " << kKey << " (spiral) of a generated Task 4 (seed 1); each segment resampled to " << popt.points
     << " progress values. Kernel C*RBF + White, initial (C, l, sigma_n^2) = (" << std::defaultfloat
     << gopt.initial.constant << ", " << gopt.initial.length_scale << ", " << gopt.initial.noise_level << std::fixed
     << "), bounds C [1e-4, 1e2], l [1e-2, 10], sigma_n^2 [1e-6, 1], alpha 1e-10, " << gopt.restarts
     << " restarts, on both sides. A fit is an x-GP and a y-GP from the raw samples. scikit-learn "
     << ref["sklearn"].as<std::string>() << " (GaussianProcessRegressor, L-BFGS-B) runs in the same process tree, "
     << "in the same run. Median of repeated runs for ours, one run for scikit-learn; "
     << std::thread::hardware_concurrency() << " cores, 1-minute load average at the start: " << load << ".\n\n"
     << "| demos | samples per axis | ours fit, wall (ms) | ours fit, CPU (ms) | scikit-learn fit, wall (s) | "
        "scikit-learn fit, CPU (s) | speed-up, wall | speed-up, CPU | LML ours (x + y) | LML scikit-learn (x + y) |\n"
     << "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
     << fit_rows;
  md << "\nLML is the log marginal likelihood at the optimum (higher is better); ours needed "
     << ours.back().evaluations << " likelihood evaluations for the 20-demo fit. scikit-learn at 1000 and 2000 "
     << "samples: `bench_gp_fit --sklearn-demos 5,10,20` (minutes). CPU time counts every thread of the "
     << "process (NumPy's BLAS may use several).\n\n"
     << "| prediction, 100 progress values | ours, wall (ms) | ours, CPU (ms) | scikit-learn, wall (ms) | "
        "scikit-learn, CPU (ms) |\n|---|---:|---:|---:|---:|\n"
     << std::setprecision(4) << "| one GP, mean and std | " << predict.one_gp.wall_ms << " | " << predict.one_gp.cpu_ms
     << " | " << std::setprecision(2) << sk_predict_ms << " | " << sk_predict_cpu_ms << " |\n"
     << std::setprecision(4) << "| retargeted primitive path (x and y, 100 points, cached grid) | "
     << predict.path_cached.wall_ms << " | " << predict.path_cached.cpu_ms << " | | |\n"
     << "| retargeted primitive path (x and y, 101 points, GP evaluated) | " << predict.path_evaluated.wall_ms << " | "
     << predict.path_evaluated.cpu_ms << " | | |\n\n"
     << "Goals: fit >= 1000x faster than scikit-learn at 500 samples with an equal or better LML; "
     << "20-demo fit < 50 ms; 100-point prediction < 0.2 ms.\n";
  return md.str();
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const fs::path repo = bench::repositoryFromArgs(argc, argv, {"bench/gp_fit_reference.py"});
    const std::optional<std::vector<int>> sklearn_demos = sklearnDemos(argc, argv);
    if (!sklearn_demos) {
      std::cerr << "usage: bench_gp_fit [--repo DIR] [--sklearn-demos 5,10,20]\n";
      return 2;
    }
    const std::string load = loadAverage();
    tasks::GeneratorOptions g;
    g.family = "task4";
    g.demos = 20;
    g.seed = 1;
    const task::TaskDir all = tasks::generate(g);
    const gp::PrimitiveOptions popt;
    const std::vector<Set> sets = sampleSets(all, popt);
    const std::vector<Ours> ours = fitOurs(sets, popt.gp);
    const Predictions predict = timePredictions(all, sets[0], popt.gp);
    const YAML::Node ref = runSklearn(repo, sets, *sklearn_demos, popt.gp);
    const std::string md = report(sets, ours, predict, ref, popt, load);
    std::cout << md;
    bench::writeResults(repo, "gp_fit", md);
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "bench_gp_fit: error: " << e.what() << "\n";
    return 1;
  }
}
