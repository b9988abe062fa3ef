// ddace path: a retargeted primitive path from a model directory, or every test segment
// of a task directory next to its generated path (for scripts/plot_paths.py).
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/eval/frechet.h"
#include "ddace/gp/canonical.h"
#include "ddace/gp/primitives.h"
#include "ddace/task/end_point.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/task/fingerprint.h"
#include "ddace/task/task_dir.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

/// The primitive library of a model directory (loaded and verified as every user of a
/// model does, pipeline::loadModel), or a library file on its own (checked by its own
/// reader: format, fingerprint digest, stored likelihoods). A directory without a
/// manifest.yaml holding a primitives.yaml is such a library on its own.
gp::PrimitiveLibrary loadLibrary(const std::string& model) {
  const fs::path p(model);
  if (fs::is_directory(p)) {
    if (fs::exists(p / "manifest.yaml")) {
      const pipeline::Model m = pipeline::loadModel(model);
      if (!m.primitives)
        throw Error(Diagnostic{model, 0, 0,
                               "a " + m.sequence.variant() +
                                   " model has no primitive library (it rolls out its own "
                                   "trajectories)"});
      return *m.primitives;
    }
    const fs::path file = p / gp::kPrimitivesFile;
    if (!fs::exists(file))
      throw Error(Diagnostic{file.string(), 0, 0,
                             "no primitive library in model directory " + model + " (train one with ddace train)"});
    return gp::PrimitiveLibrary::load(file.string());
  }
  return gp::PrimitiveLibrary::load(model);
}

Eigen::Vector2d parsePoint(const Args& args, const std::string& flag) {
  const std::string text = args.require(flag);
  const auto comma = text.find(',');
  auto number = [&](const std::string& s) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !std::isfinite(v))
      throw Error("option " + flag + ": '" + text + "' is not X,Y in metres (two finite numbers)");
    return v;
  };
  if (comma == std::string::npos) throw Error("option " + flag + ": '" + text + "' is not X,Y in metres");
  return {number(text.substr(0, comma)), number(text.substr(comma + 1))};
}

void writePath(std::ostream& out, const gp::GeneratedPath& path) {
  out << "i,progress,x,y,stddev\n" << std::setprecision(9);
  const size_t n = path.points.size();
  for (size_t i = 0; i < n; ++i)
    out << i << "," << static_cast<double>(i) / (n - 1) << "," << path.points[i].x() << "," << path.points[i].y() << ","
        << path.stddev[i] << "\n";
}

int onePath(const Args& args, const gp::PrimitiveLibrary& lib) {
  const std::string key = args.require("--key");
  const long points = args.getInt("--points", 100);
  if (points < 2 || points > 100000) throw Error("--points must be between 2 and 100000");
  const long step = args.getInt("--step", -1);
  if (step < -1 || step > 100000) throw Error("--step must be a step index (0-based) between 0 and 100000");
  const gp::GeneratedPath path = lib.generate(key, parsePoint(args, "--start"), parsePoint(args, "--goal"),
                                              static_cast<int>(points), static_cast<int>(step));
  const std::string note = path.fell_back ? "# " + key + " was never demonstrated: fell back to " + path.source_key
                                          : "# primitive " + path.source_key;
  if (args.has("--csv")) {
    std::ostringstream f;
    writePath(f, path);
    writeTextFile(args.get("--csv", ""), f.str());
    std::cout << note.substr(2) << "; " << points << " points written to " << args.get("--csv", "") << "\n";
  } else {
    std::cout << note << "\n";
    writePath(std::cout, path);
  }
  return 0;
}

/// Every motion segment of every demonstration in TASKDIR with the path generated for its
/// start, goal and step (with --by-name: the names' primitives, not the roles'); prints the
/// mean normalised Fréchet distance per key.
int demoPaths(const Args& args, const gp::PrimitiveLibrary& trained) {
  const std::string dir = args.get("--demos", "");
  if (!args.has("--csv")) throw Error("--demos needs --csv FILE for the paths");
  const task::TaskDir task = task::loadTaskDir(dir);
  if (!args.has("--allow-other-task"))
    task::requireSameTask(
        trained.taskFingerprint(), args.positional(0, "MODELDIR") + " (task '" + trained.taskName() + "')",
        task::fingerprintOf(task), dir + " (task '" + task.spec.name + "')", "pass --allow-other-task");
  // Other numbers or names of the same kinds: the library bound to them (refused naming a
  // kind one of them lacks).
  const gp::PrimitiveLibrary lib =
      task.spec.entityNames() == trained.entityNames() ? trained : trained.boundTo(task.spec);
  const bool by_name = args.has("--by-name");
  const task::EndPointModel ends = by_name ? lib.endPoints().byName() : lib.endPoints();
  std::ofstream f(args.get("--csv", ""));
  if (!f) throw Error(Diagnostic{args.get("--csv", ""), 0, 0, "cannot open for writing"});
  f << "demo,segment,key,source_key,kind,i,x,y,stddev\n" << std::setprecision(9);
  std::map<std::string, std::pair<double, int>> fd;
  int fell_back = 0;
  for (const auto& demo : task.demos) {
    const std::string name = fs::path(demo.source).filename().string();
    for (size_t s = 0; s < demo.segments.size(); ++s) {
      const task::Segment& seg = demo.segments[s];
      if (!seg.token.isMotion()) continue;
      const std::vector<Eigen::Vector2d> truth = demo.segmentPath(seg);
      if ((truth.back() - truth.front()).norm() < gp::kMinMotionLength) continue;
      const std::string key = task::tokenKey(seg.token, task.spec);
      const gp::GeneratedPath g = lib.generate(
          seg.token, truth.front(), task::segmentEndPoint(task.spec, ends, demo, seg), 100, by_name ? -1 : seg.step);
      fell_back += g.fell_back;
      for (size_t i = 0; i < truth.size(); ++i)
        f << name << "," << s << "," << key << "," << g.source_key << ",demo," << i << "," << truth[i].x() << ","
          << truth[i].y() << ",0\n";
      for (size_t i = 0; i < g.points.size(); ++i)
        f << name << "," << s << "," << key << "," << g.source_key << ",generated," << i << "," << g.points[i].x()
          << "," << g.points[i].y() << "," << g.stddev[i] << "\n";
      auto& [sum, count] = fd[key];
      sum += eval::normalisedFrechet(g.points, truth);
      ++count;
    }
  }
  if (!f) throw Error(Diagnostic{args.get("--csv", ""), 0, 0, "cannot write"});
  std::cout << "key                      segments  mean normalised FD\n" << std::fixed << std::setprecision(4);
  for (const auto& [key, v] : fd)
    std::cout << std::left << std::setw(25) << key << std::right << std::setw(8) << v.second << "  " << std::setw(10)
              << v.first / v.second << "\n";
  if (fell_back) std::cout << fell_back << " segments used a fallback primitive\n";
  std::cout << "paths written to " << args.get("--csv", "") << "\n";
  return 0;
}

/// The primitives of a library: key, segments, hyper-parameters and likelihood per axis.
int listPrimitives(const gp::PrimitiveLibrary& lib) {
  std::cout << "task " << lib.taskName() << ": " << lib.primitives().size() << " primitives\n"
            << "key                      segments  axis        C   length_scale    noise_level         LML\n";
  for (const auto& [key, p] : lib.primitives()) {
    for (int axis = 0; axis < 2; ++axis) {
      const gp::GaussianProcess& g = axis == 0 ? p.x : p.y;
      std::cout << std::left << std::setw(25) << (axis == 0 ? key : "") << std::right << std::setw(8)
                << (axis == 0 ? std::to_string(p.segments) : "") << "  " << std::setw(4) << (axis == 0 ? "x" : "y")
                << std::scientific << std::setprecision(3) << std::setw(11) << g.params().constant << std::setw(15)
                << g.params().length_scale << std::setw(15) << g.params().noise_level << std::fixed
                << std::setprecision(2) << std::setw(12) << g.logMarginalLikelihood() << "\n";
    }
  }
  return 0;
}

int runPath(const std::vector<std::string>& argv) {
  Args args(argv, {"--key", "--start", "--goal", "--points", "--step", "--csv", "--demos"},
            {"--list", "--allow-other-task", "--by-name"});
  args.expectAtMostPositional(1);
  const gp::PrimitiveLibrary lib = loadLibrary(args.positional(0, "MODELDIR"));
  if (args.has("--list")) return listPrimitives(lib);
  if (args.has("--demos")) {
    for (const char* flag : {"--key", "--start", "--goal", "--points", "--step"})
      if (args.has(flag)) throw Error(std::string("option ") + flag + " cannot be combined with --demos");
    return demoPaths(args, lib);
  }
  if (args.has("--by-name")) throw Error("option --by-name is for --demos (--key without --step is by name)");
  return onePath(args, lib);
}

DDACE_COMMAND({"path",
               "ddace path MODELDIR --key E:ACTION:T --start X,Y --goal X,Y [--step K] [--points N] [--csv FILE] | "
               "ddace path MODELDIR --demos TASKDIR --csv FILE [--by-name] [--allow-other-task] | "
               "ddace path MODELDIR --list",
               "print or write a primitive path retargeted to a start and goal (metres, table frame), the motion "
               "in step K (0-based: a role's primitive where the library keys its class by role), "
               "or every motion segment of TASKDIR next to its generated path with the mean FD per key "
               "(--by-name: the names' primitives and end points only), or list the primitives",
               runPath});

}  // namespace
}  // namespace ddace::cli
