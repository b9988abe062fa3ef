#include "ddace/pipeline/evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <ostream>

#include <nlohmann/json.hpp>

#include "ddace/common/file.h"
#include "ddace/common/sha256.h"
#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/diff_drive_execution.h"
#include "ddace/pipeline/perturbation.h"
#include "ddace/task/end_point.h"

namespace ddace::pipeline {

namespace fs = std::filesystem;

Model trainModel(const task::TaskDir& train, const tgn::TrainOptions& options, const std::string& model_dir,
                 std::ostream* progress) {
  Model m{tgn::SequenceModel::train(train, options, progress), nullptr};
  std::vector<std::string> bound;
  if (options.variant != tgn::Variant::Gnn) {
    m.primitives = std::make_shared<gp::PrimitiveLibrary>(gp::PrimitiveLibrary::fit(train));
    std::error_code ec;
    fs::create_directories(model_dir, ec);
    if (ec) throw Error(Diagnostic{model_dir, 0, 0, "cannot create the model directory: " + ec.message()});
    m.primitives->save((fs::path(model_dir) / gp::kPrimitivesFile).string());
    bound.push_back(gp::kPrimitivesFile);
  }
  m.sequence.save(model_dir, bound);  // the manifest last: it binds the files written before it
  return m;
}

Model loadModel(const std::string& model_dir) {
  Model m{tgn::SequenceModel::load(model_dir), nullptr};
  const tgn::ModelInfo& info = m.sequence.info();
  const std::string manifest = (fs::path(model_dir) / "manifest.yaml").string();
  const std::string path = (fs::path(model_dir) / gp::kPrimitivesFile).string();
  const auto bound = info.files.find(gp::kPrimitivesFile);
  if (info.variant == tgn::Variant::Gnn) {
    if (bound != info.files.end())
      throw Error(Diagnostic{manifest, 0, 0, "a gnn model has no primitive library, but the manifest lists one"});
    return m;
  }
  if (bound == info.files.end())
    throw Error(Diagnostic{manifest, 0, 0,
                           std::string("lists no ") + gp::kPrimitivesFile + " (a " + m.sequence.variant() +
                               " model needs its primitive library): retrain the model"});
  // The bytes parsed are the bytes checked.
  const std::string text = readTextFile(path);
  const std::string actual = sha256Hex(text);
  if (text.size() != bound->second.bytes || actual != bound->second.sha256)
    throw Error(Diagnostic{path, 0, 0,
                           "edited, replaced or corrupted: " + std::to_string(text.size()) + " bytes with SHA-256 " +
                               actual + ", " + manifest + " records " + std::to_string(bound->second.bytes) +
                               " bytes with " + bound->second.sha256});
  m.primitives = std::make_shared<gp::PrimitiveLibrary>(gp::PrimitiveLibrary::parse(text, path));
  if (m.primitives->taskFingerprint().digest() != info.fingerprint.digest())
    throw Error(Diagnostic{path, 0, 0,
                           "fitted on another task than the sequence model (task fingerprint " +
                               m.primitives->taskFingerprint().digest() + ", " + manifest + " has " +
                               info.fingerprint.digest() + ")"});
  return m;
}

namespace {

/// "3 robot, 1 object:box, 2 goal": the entities of `spec` counted by kind.
std::string countsByKind(const task::TaskSpec& spec) {
  std::map<std::string, int> counts;
  for (const auto& e : spec.entities) ++counts[tgn::kindKey(e)];
  std::string s;
  for (const auto& [kind, n] : counts) s += (s.empty() ? "" : ", ") + std::to_string(n) + " " + kind;
  return s;
}

}  // namespace

ModelForTask modelForTask(const Model& model, const std::string& model_dir, const task::TaskSpec& spec,
                          const task::TaskFingerprint& fingerprint, const std::string& task_file, bool allow_other_task,
                          const std::string& override_hint) {
  const task::TaskSpec& own = model.sequence.spec();
  const std::string manifest = (fs::path(model_dir) / "manifest.yaml").string() + ", task '" + own.name + "'";
  const std::string task = task_file + " (task '" + spec.name + "')";
  std::vector<std::string> own_names = own.entityNames(), names = spec.entityNames();
  if (own_names == names) {
    if (!allow_other_task)
      task::requireSameTask(model.sequence.info().fingerprint, manifest, fingerprint, task, override_hint);
    return {model, ""};
  }
  std::sort(own_names.begin(), own_names.end());
  std::sort(names.begin(), names.end());
  if (own_names == names)
    throw Error("the model in " + model_dir + " lists the entities in another order than " + task_file +
                ": keep task.yaml's order of the training directory");
  if (!allow_other_task) {
    // Other numbers of the same kinds: the same task but for the entities and what names
    // or counts them (goal conditions, steps per demonstration).
    task::TaskFingerprint as_model = fingerprint;
    const task::TaskFingerprint& trained = model.sequence.info().fingerprint;
    if (own.name == spec.name) {
      as_model.entities = trained.entities;
      as_model.goal_conditions = trained.goal_conditions;
      if (!as_model.step_counts.empty()) as_model.step_counts = trained.step_counts;
    }
    task::requireSameTask(trained, manifest, as_model, task, override_hint);
  }
  ModelForTask bound{model, ""};
  try {
    bound.model.sequence = model.sequence.boundTo(spec);
    if (model.primitives)
      bound.model.primitives = std::make_shared<gp::PrimitiveLibrary>(model.primitives->boundTo(spec));
  } catch (const Error& e) {
    throw Error("the model in " + model_dir + " (" + countsByKind(own) + ") cannot run on the entities of " + task +
                " (" + countsByKind(spec) + "): " + e.what());
  }
  bound.note = "note: the model in " + model_dir + " was trained on " + countsByKind(own) + ", " + task_file + " has " +
               countsByKind(spec) + ": entities bound by kind (the model runs on " + model.sequence.transfer().text() +
               ")";
  return bound;
}

ModelForTask modelForTask(const Model& model, const std::string& model_dir, const task::TaskDir& test,
                          const std::string& test_dir, bool allow_other_task) {
  return modelForTask(model, model_dir, test.spec, task::fingerprintOf(test), test_dir + "/task.yaml", allow_other_task,
                      "pass --allow-other-task");
}

namespace {

/// A trial from a gnn rollout: its own steps, its own trajectories.
exec::Trial trialFromRollout(const task::Demonstration& r, int max_rows) {
  exec::Trial t;
  t.predicted = r.steps;
  t.ended = static_cast<int>(r.rows()) < max_rows;
  for (const auto& seg : r.segments) {
    exec::ExecutedToken ex;
    ex.token = seg.token;
    ex.step = seg.step;
    ex.executed = r.segmentPath(seg);
    ex.start = ex.executed.front();
    ex.goal = r.segmentGoal(seg);  // the gnn learns no end points: its own rollout's goal
    t.executed.push_back(std::move(ex));
  }
  t.snapshots = r.snapshots;
  if (r.rows()) t.final_positions = r.positions.back();
  return t;
}

std::string twoDecimals(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", v);
  return text;
}

std::string tokensOf(const std::vector<task::Step>& steps, size_t k, const task::TaskSpec& spec) {
  if (k >= steps.size()) return "{END}";
  std::string out = "{";
  for (const auto& t : steps[k].tokens) out += (out.size() > 1 ? " " : "") + task::tokenKey(t, spec);
  return out + "}";
}

/// The first step whose tokens differ (the diagnostic line of a failed trial).
std::string firstDifference(const task::TaskSpec& spec, const std::vector<task::Step>& demonstrated,
                            const std::vector<task::Step>& predicted) {
  for (size_t k = 0; k < std::max(demonstrated.size(), predicted.size()); ++k) {
    const std::string p = tokensOf(predicted, k, spec), d = tokensOf(demonstrated, k, spec);
    if (p != d) return "step " + std::to_string(k + 1) + ": predicted " + p + " demonstrated " + d;
  }
  return "";
}

/// Each token's time in a trial on points: a robot's control cycles along its executed
/// path (the points model's default robot), an object its path at cruise speed (carried),
/// an in-place token none.
std::vector<std::vector<double>> pointDurations(const task::TaskSpec& spec, const exec::Trial& trial) {
  std::vector<std::vector<double>> out(trial.predicted.size());
  const double rate_hz = exec::DiffDriveParams{}.rate_hz, speed = exec::FollowerGains{}.cruise_speed_mps;
  for (const exec::ExecutedToken& ex : trial.executed) {
    double length = 0;
    for (size_t i = 1; i < ex.executed.size(); ++i) length += (ex.executed[i] - ex.executed[i - 1]).norm();
    const bool robot = spec.entities[static_cast<size_t>(ex.token.entity)].kind == task::EntityKind::Robot;
    const double steps = ex.executed.empty() ? 0 : static_cast<double>(ex.executed.size() - 1);
    out.at(static_cast<size_t>(ex.step)).push_back(!ex.token.isMotion() ? 0 : robot ? steps / rate_hz : length / speed);
  }
  return out;
}

}  // namespace

exec::BodiesExecutionParams bodiesParams(const EvalOptions& options, const task::TaskSpec& spec) {
  exec::BodiesExecutionParams p;
  p.config = options.config;
  p.arrival_radius_m = spec.arrival_radius;
  p.noise_m = options.noise_m;
  p.seed = options.seed;
  // Tracking noise is eval's own (--noise, --seed), not the mock robots' of the config.
  const exec::DiffDriveParams hamster = exec::simulatedHamster();
  p.config.robot.yaw_noise_rad = hamster.yaw_noise_rad;
  p.config.robot.seed = hamster.seed;
  p.config.safety.enabled = options.safety_filter && options.config.safety.enabled;
  return p;
}

std::vector<std::string> describeWaits(const exec::Dispatch& d, const task::TaskSpec& spec) {
  std::vector<std::string> out;
  for (const exec::Wait& w : d.waits()) {
    std::string line = "step " + std::to_string(w.token.step + 1) + " " + task::tokenKey(d.token(w.token), spec) +
                       " at " + twoDecimals(w.start_s) + " s";
    if (w.released)
      line += ", released by " + task::tokenKey(d.token(w.released_by), spec) + " at " + twoDecimals(w.ready_s) + " s";
    if (w.held)
      line +=
          ", held until " + task::tokenKey(d.token(w.held_by), spec) + " started (places taken from the inside out)";
    out.push_back(line);
  }
  return out;
}

bool policyReadsScene(const tgn::ModelInfo& info) {
  return info.variant != tgn::Variant::Scene || info.plan.relative_features;
}

bool policyReadsScene(const Model& model) {
  return policyReadsScene(model.sequence.info());
}

Evaluation evaluate(const Model& model, const task::TaskDir& test, const EvalOptions& options) {
  Evaluation e;
  e.task = model.sequence.spec().name;
  e.variant = model.sequence.variant();
  const bool gnn = model.sequence.info().variant == tgn::Variant::Gnn;
  e.execution = options.execution;
  const bool bodies = options.bodies && options.config.table.bodies;
  const bool filter = options.safety_filter && options.config.safety.enabled;
  if (options.execution == "diffdrive")
    e.execution += bodies ? (filter ? " with bodies" : " with bodies, no filter") : " (points)";
  const task::TaskSpec& spec = test.spec;
  e.entity_names = spec.entityNames();
  e.arrival_radius_m = spec.arrival_radius;
  for (size_t i = 0; i < spec.entities.size(); ++i)
    if (spec.entities[i].kind == task::EntityKind::Robot) e.robot_entities.insert(static_cast<int>(i));

  if (options.execution == "diffdrive" && bodies && options.coordinated) {
    if (gnn) throw Error("a coordinated run needs a model with primitives (the gnn variant rolls out its own)");
    e.execution += ", coordinated";
    e.dispatch = exec::toString(options.dispatch);
    exec::BodiesExecutionParams table = bodiesParams(options, spec);
    for (size_t i = 0; i < test.demos.size(); ++i) {
      const task::Demonstration& gt = test.demos[i];
      table.first_trial = i + 1;  // the noise of the simulator's trial i: the two runs compare trial by trial
      CoordinatedRun r = runCoordinated(model, spec, gt, {}, exec::CoordinatorConfig{}.max_replans, options.dispatch,
                                        options.seed * 1000003ULL + i, &table, options.speed_spread);
      e.precedence_violations += r.precedence_violations;
      e.waits.push_back(r.waits);
      e.async_bound_s.push_back(r.async_bound_s);
      r.score.demo = gt.source;
      e.scores.push_back(r.score);
      e.first_difference.push_back(r.finished ? firstDifference(spec, gt.steps, r.trial.predicted) : r.reason);
      if (!r.finished) r.trial.failures.push_back("not finished: " + r.reason);
      e.trials.push_back(std::move(r.trial));
    }
    e.summary = eval::summarise(e.scores);
    return e;
  }
  std::unique_ptr<exec::ExecutionModel> execution;
  if (options.execution == "ideal") {
    execution = std::make_unique<exec::IdealExecution>();
  } else if (options.execution == "diffdrive" && bodies) {
    execution = std::make_unique<exec::BodiesExecution>(bodiesParams(options, spec));
  } else if (options.execution == "diffdrive") {
    execution = std::make_unique<exec::DiffDriveExecution>(spec.arrival_radius, options.noise_m, options.seed);
  } else {
    throw Error("--execution '" + options.execution + "' is not one of ideal, diffdrive");
  }

  // A gnn model has no primitives (it rolls out displacements).
  const task::EndPointModel ends = !model.primitives       ? task::EndPointModel{}
                                   : options.paths_by_name ? model.primitives->endPoints().byName()
                                                           : model.primitives->endPoints();
  for (const auto& gt : test.demos) {
    exec::Trial trial;
    if (gnn) {
      // Room for the ground truth plus two more steps' worth of frames, as the spec's limit.
      const int max_rows = static_cast<int>(gt.rows() * (gt.steps.size() + 2) / std::max<size_t>(1, gt.steps.size()));
      trial = trialFromRollout(tgn::rolloutGnn(model.sequence, gt, max_rows), max_rows);
    } else {
      // The paths of a step are asked for after its decision: the step they stand in.
      int step = -1;
      const auto policy = [&](const std::vector<task::Snapshot>& history) {
        step = static_cast<int>(history.size()) - 1;
        const tgn::Prediction p = model.sequence.predictNext(history);
        return exec::Decision{p.end, p.tokens};
      };
      const auto paths = [&](const task::Token& token, const Eigen::Vector2d& s, const Eigen::Vector2d& g) {
        return model.primitives->generate(token, s, g, 100, options.paths_by_name ? -1 : step).points;
      };
      trial = exec::runTrial(spec, gt, policy, paths, *execution, ends);
    }
    if (options.execution == "diffdrive" && !bodies && !gnn) {
      std::vector<std::vector<task::Token>> steps;
      for (const task::Step& k : trial.predicted) steps.push_back(k.tokens);
      const exec::Dispatch d =
          exec::scheduleSteps(spec, model.sequence.info().dependencies, options.dispatch, policyReadsScene(model),
                              steps, pointDurations(spec, trial), nullptr);
      trial.makespan_s = d.makespan();
      e.dispatch = exec::toString(options.dispatch);
      e.precedence_violations += d.violations();
      e.waits.push_back(describeWaits(d, spec));
    }
    e.scores.push_back(eval::scoreTrial(spec, gt, trial, gnn));
    e.first_difference.push_back(firstDifference(spec, gt.steps, trial.predicted));
    e.trials.push_back(std::move(trial));
  }
  e.summary = eval::summarise(e.scores);
  return e;
}

namespace {
/// Over the coordinated trials that finished (async_bound_s > 0): the mean async bound and
/// the mean makespan of the same trials (0 when none).
double meanAsyncBound(const Evaluation& e) {
  double sum = 0;
  int n = 0;
  for (double b : e.async_bound_s)
    if (b > 0) sum += b, ++n;
  return n ? sum / n : 0;
}
double meanFinishedMakespan(const Evaluation& e) {
  double sum = 0;
  int n = 0;
  for (size_t i = 0; i < e.async_bound_s.size() && i < e.scores.size(); ++i)
    if (e.async_bound_s[i] > 0) sum += e.scores[i].makespan_s, ++n;
  return n ? sum / n : 0;
}
}  // namespace

void printEvaluation(const Evaluation& e, std::ostream& out) {
  char line[256];
  std::snprintf(line, sizeof line, "%-16s %7s %6s %6s %7s %7s\n", "trial", "steps", "END", "GCR", "FD", "success");
  out << line;
  for (size_t i = 0; i < e.scores.size(); ++i) {
    const auto& s = e.scores[i];
    std::snprintf(line, sizeof line, "%-16s %3d/%-3d %6s %6.3f %7.4f %7s\n", fs::path(s.demo).filename().c_str(),
                  s.correct_steps, s.gt_steps, s.ended_correctly ? "yes" : "no", s.gcr(), s.meanFd(),
                  s.success ? "yes" : "no");
    out << line;
    if (!s.success && i < e.first_difference.size() && !e.first_difference[i].empty())
      out << "    " << e.first_difference[i] << "\n";
    if (i < e.waits.size())
      for (const std::string& w : e.waits[i]) out << "    " << w << "\n";
    if (s.bodies) {
      std::snprintf(line, sizeof line, "    bodies: %d collisions, min clearance %.1f mm, makespan %.1f s\n",
                    s.collisions, s.min_clearance_m * 1000, s.makespan_s);
      out << line;
      const exec::Trial& t = e.trials[i];
      for (const auto& c : t.body_report.collisions)
        out << "    collision at " << c.time_s << " s: " << e.entity_names.at(c.a) << " touched "
            << e.entity_names.at(c.b) << "\n";
      for (const auto& f : t.failures) out << "    " << f << "\n";
      for (const eval::ObjectLeftShort& o : s.objects_left_short) out << "    " << o.describe() << "\n";
      for (const auto& ex : t.executed)  // robots that stopped outside the arrival radius
        if (ex.token.isMotion() && e.robot_entities.count(ex.token.entity) &&
            !task::arrived(ex.executed.back(), ex.goal, e.arrival_radius_m)) {
          std::snprintf(line, sizeof line, "    step %d: %s:%s stopped %.1f cm from its end point\n", ex.step + 1,
                        e.entity_names.at(ex.token.entity).c_str(), ex.token.action.c_str(),
                        (ex.executed.back() - ex.goal).norm() * 100);
          out << line;
        }
    }
  }
  const auto& m = e.summary;
  // The task's name apart: a zoo rule's name in words is longer than the buffer.
  out << e.task << ", variant " << e.variant << ", execution " << e.execution << ": ";
  std::snprintf(line, sizeof line, "%d trials  OSR %.3f  SSR %.3f  GCR %.3f  FD %.4f\n", m.trials, m.osr, m.ssr, m.gcr,
                m.fd);
  out << line;
  if (m.bodies) {
    std::snprintf(line, sizeof line,
                  "bodies: %d collisions in %d of %d trials, min clearance %.1f mm, mean makespan %.1f s\n",
                  m.collisions, m.trials_with_collision, m.trials, m.min_clearance_m * 1000, m.makespan_s);
    out << line;
  }
  if (!e.dispatch.empty()) {
    std::snprintf(line, sizeof line, "dispatch %s: mean makespan %.2f s, %d precedence violations\n",
                  e.dispatch.c_str(), m.makespan_s, e.precedence_violations);
    out << line;
    const double bound = meanAsyncBound(e);
    if (bound > 0) {
      std::snprintf(line, sizeof line,
                    "  async with every token taking the time it took here: mean makespan %.2f s (%.3fx), over the "
                    "finished trials\n",
                    bound, bound / meanFinishedMakespan(e));
      out << line;
    }
  }
}

std::string evaluationJson(const Evaluation& e) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["task"] = e.task;
  j["variant"] = e.variant;
  j["execution"] = e.execution;
  j["trials"] = e.summary.trials;
  j["osr"] = e.summary.osr;
  j["ssr"] = e.summary.ssr;
  j["gcr"] = e.summary.gcr;
  j["fd"] = num(e.summary.fd);
  if (e.summary.bodies) {
    j["collisions"] = e.summary.collisions;
    j["trials_with_collision"] = e.summary.trials_with_collision;
    j["min_clearance_m"] = num(e.summary.min_clearance_m);
    j["makespan_s"] = e.summary.makespan_s;
  }
  if (!e.dispatch.empty()) {
    j["dispatch"] = e.dispatch;
    j["makespan_s"] = e.summary.makespan_s;
    j["precedence_violations"] = e.precedence_violations;
    if (meanAsyncBound(e) > 0) j["async_bound_s"] = meanAsyncBound(e);
  }
  j["per_trial"] = nlohmann::json::array();
  for (size_t i = 0; i < e.scores.size(); ++i) {
    const auto& s = e.scores[i];
    j["per_trial"].push_back({{"demo", fs::path(s.demo).filename().string()},
                              {"success", s.success},
                              {"ssr", s.ssr()},
                              {"gcr", s.gcr()},
                              {"fd", num(s.meanFd())},
                              {"steps_correct", s.correct_steps},
                              {"steps_ground_truth", s.gt_steps},
                              {"steps_predicted", s.predicted_steps},
                              {"ended_correctly", s.ended_correctly},
                              {"goal_conditions_hold", s.goal_conditions_hold},
                              {"first_difference", i < e.first_difference.size() ? e.first_difference[i] : ""}});
    if (i < e.trials.size() && !e.trials[i].final_positions.empty()) {  // where every entity ended, [x, y] metres
      nlohmann::json at = nlohmann::json::array();
      for (const Eigen::Vector2d& p : e.trials[i].final_positions) at.push_back({num(p.x()), num(p.y())});
      j["per_trial"].back()["final_positions"] = at;
    }
    if (s.bodies) {
      auto& t = j["per_trial"].back();
      t["collisions"] = s.collisions;
      t["min_clearance_m"] = num(s.min_clearance_m);
      t["makespan_s"] = s.makespan_s;
      t["failures"] = e.trials[i].failures;
      for (const eval::ObjectLeftShort& o : s.objects_left_short) t["failures"].push_back(o.describe());
    } else if (!e.dispatch.empty()) {
      j["per_trial"].back()["makespan_s"] = s.makespan_s;
      if (i < e.waits.size()) j["per_trial"].back()["waits"] = e.waits[i];
    }
    if (i < e.async_bound_s.size()) j["per_trial"].back()["async_bound_s"] = e.async_bound_s[i];
  }
  return j.dump(2) + "\n";
}

}  // namespace ddace::pipeline
