#include "ddace/tasks/generators.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "ddace/common/random.h"

namespace ddace::tasks {

namespace {

using Eigen::Vector2d;
using task::EntityKind;

/// A path shape in the canonical frame: f(0) = (0,0), f(1) = (1,0).
struct Shape {
  enum Kind { Straight, Arc, SCurve, Spiral } kind = Straight;
  double amplitude = 0;  ///< fraction of the start-goal distance

  Vector2d at(double u, double a) const {
    switch (kind) {
      case Straight: return {u, 0};
      case Arc: return {u, a * std::sin(M_PI * u)};
      case SCurve: return {u, a * std::sin(2 * M_PI * u)};
      case Spiral: {
        // A loop and a half whose radius swells and vanishes: a spiral-like path.
        const double r = a * std::sin(M_PI * u), th = 3 * M_PI * u;
        return {u + r * std::sin(th), r * (1 - std::cos(th))};
      }
    }
    return {u, 0};
  }
};

/// One token of a planned step; target empty = in-place action.
struct Move {
  std::string entity, action, target;
  Shape shape;
};

struct Plan {
  task::TaskSpec spec;
  std::map<std::string, Vector2d> layout;  ///< template start positions, metres
  double layout_jitter = 0.06;             ///< uniform +- per coordinate, metres
  std::vector<std::vector<Move>> steps;
};

constexpr double kSpeed = 0.15;          // m/s, nominal robot speed
constexpr double kMinStepDuration = 1.0; // s
constexpr int kIdleRowsBefore = 4, kIdleRowsBetween = 3, kIdleRowsAfter = 4;

void addEntity(Plan& p, const std::string& name, EntityKind kind, const std::string& type,
               Vector2d where) {
  p.spec.entities.push_back({name, kind, type});
  p.layout[name] = where;
}

Plan task1() {
  Plan p;
  p.spec.name = "task1_heterogeneous_transport";
  p.spec.actions = {"drive", "fly", "transfer", "stop"};
  addEntity(p, "R1", EntityKind::Robot, "hamster", {0.15, 0.30});
  addEntity(p, "R2", EntityKind::Robot, "hamster", {0.80, 0.62});
  addEntity(p, "D1", EntityKind::Robot, "uav", {0.33, 0.72});
  addEntity(p, "C1", EntityKind::Object, "cargo", {0.15, 0.30});  // loaded on R1
  addEntity(p, "W1", EntityKind::Object, "river", {0.50, 0.50});
  addEntity(p, "G1", EntityKind::Goal, "", {0.85, 0.15});
  p.spec.goal_conditions = {{"C1", "G1", 0.05}};
  const Shape drive{Shape::Arc, 0.12}, fly{Shape::Straight, 0};
  p.steps = {
      {{"R1", "drive", "D1", drive}, {"C1", "drive", "D1", drive}},
      {{"R1", "transfer", "", {}}, {"D1", "transfer", "", {}}},
      {{"R1", "stop", "", {}}, {"D1", "fly", "R2", fly}, {"C1", "fly", "R2", fly}},
      {{"D1", "transfer", "", {}}, {"R2", "transfer", "", {}}},
      {{"R2", "drive", "G1", drive}, {"C1", "drive", "G1", drive}, {"D1", "stop", "", {}}},
  };
  return p;
}

Plan task2(int robots) {
  Plan p;
  p.spec.name = "task2_scalability_" + std::to_string(robots) + "_robots";
  p.spec.actions = {"move", "stop"};
  const std::vector<Vector2d> where = {
      {0.08, 0.15}, {0.08, 0.45}, {0.25, 0.30}, {0.50, 0.40}, {0.30, 0.60}, {0.55, 0.75},
      {0.80, 0.88}, {0.75, 0.55}, {0.88, 0.30}, {0.45, 0.12}, {0.70, 0.15}};
  auto R = [](int i) { return "R" + std::to_string(i); };
  for (int i = 1; i <= robots; ++i) addEntity(p, R(i), EntityKind::Robot, "hamster", where[i - 1]);
  addEntity(p, "G1", EntityKind::Goal, "", {0.95, 0.05});
  p.layout_jitter = 0.04;
  const Shape move{Shape::Straight, 0};
  const std::vector<std::vector<Move>> full = {
      {{"R1", "move", "R3", move}, {"R2", "move", "R3", move}},
      {{"R3", "move", "R5", move}},  // R3 proceeds toward R4 via R5 ...
      {{"R3", "move", "R4", move}},  // ... then on to R4
      {{"R4", "move", "R6", move}, {"R5", "move", "R6", move}},
      {{"R5", "stop", "", {}}},      // R5 halts on arrival ...
      {{"R4", "move", "R7", move}},  // ... while R4 continues to R7
      {{"R6", "move", "R8", move}, {"R7", "move", "R9", move}},
      {{"R8", "move", "R9", move}},
      {{"R9", "move", "R11", move}, {"R10", "move", "R11", move}},
      {{"R11", "move", "G1", move}},
  };
  // Fewer robots: drop tokens naming a robot beyond R<robots>, drop emptied steps,
  // and let R<robots> finish by moving to the goal.
  auto present = [&](const std::string& n) { return n.empty() || p.spec.entityIndex(n) >= 0; };
  for (const auto& step : full) {
    std::vector<Move> kept;
    for (const auto& m : step)
      if (present(m.entity) && present(m.target)) kept.push_back(m);
    if (!kept.empty()) p.steps.push_back(kept);
  }
  if (robots < 11) p.steps.push_back({{R(robots), "move", "G1", move}});
  p.spec.goal_conditions = {{R(robots), "G1", 0.05}};
  return p;
}

Plan task3(int actions) {
  Plan p;
  p.spec.name = "task3_ball_screen_" + std::to_string(actions) + "_actions";
  p.spec.actions = {"move", "stop"};
  if (actions >= 3) p.spec.actions.push_back("dribble");
  if (actions >= 4) p.spec.actions.push_back("pass");
  const std::string dribble = actions >= 3 ? "dribble" : "move";
  const std::string pass_ball = actions >= 4 ? "pass" : "move";
  const std::string pass_self = actions >= 4 ? "pass" : "stop";
  addEntity(p, "R1", EntityKind::Robot, "hamster", {0.62, 0.62});  // defender
  addEntity(p, "R2", EntityKind::Robot, "hamster", {0.15, 0.25});  // passer
  addEntity(p, "R3", EntityKind::Robot, "hamster", {0.45, 0.20});  // shooter
  addEntity(p, "B1", EntityKind::Object, "ball", {0.15, 0.25});    // with the passer
  addEntity(p, "G1", EntityKind::Goal, "hoop", {0.85, 0.85});
  p.spec.goal_conditions = {{"B1", "G1", 0.05}, {"R3", "G1", 0.05}};
  const Shape straight{Shape::Straight, 0}, approach{Shape::Arc, 0.15},
      around{Shape::SCurve, 0.12};
  p.steps = {
      {{"R1", "move", "R3", approach}, {"R2", pass_self, "", {}}, {"B1", pass_ball, "R3", straight}},
      {{"R2", "move", "R1", approach}},  // the screen
      {{"R1", "stop", "", {}}, {"R3", dribble, "G1", around}, {"B1", dribble, "G1", around}},
      {{"R3", "stop", "", {}}},  // at the goal with the ball
  };
  return p;
}

Plan task4() {
  Plan p;
  p.spec.name = "task4_trajectory_shape";
  p.spec.actions = {"move"};
  addEntity(p, "R1", EntityKind::Robot, "hamster", {0.10, 0.22});
  addEntity(p, "R2", EntityKind::Robot, "hamster", {0.10, 0.78});
  addEntity(p, "R3", EntityKind::Robot, "hamster", {0.45, 0.30});
  addEntity(p, "R4", EntityKind::Robot, "hamster", {0.45, 0.70});
  addEntity(p, "G1", EntityKind::Goal, "", {0.88, 0.50});
  p.layout_jitter = 0.05;
  p.spec.goal_conditions = {{"R3", "G1", 0.05}, {"R4", "G1", 0.05}};
  p.steps = {
      {{"R1", "move", "R3", {Shape::Arc, -0.30}}, {"R2", "move", "R4", {Shape::Arc, 0.30}}},
      {{"R3", "move", "G1", {Shape::Spiral, 0.22}}, {"R4", "move", "G1", {Shape::Spiral, -0.22}}},
  };
  return p;
}

double smoothstep(double s) { return s * s * (3 - 2 * s); }

/// The path of a motion from `from` to `to` with `shape` and amplitude `a`, at progress u.
Vector2d pathPoint(const Shape& shape, double a, const Vector2d& from, const Vector2d& to, double u) {
  const Vector2d d = to - from;
  const Vector2d c = shape.at(u, a);
  const Vector2d perp(-d.y(), d.x());
  return from + c.x() * d + c.y() * perp;
}

double pathLength(const Shape& shape, double a, const Vector2d& from, const Vector2d& to) {
  double len = 0;
  Vector2d prev = from;
  for (int i = 1; i <= 200; ++i) {
    const Vector2d q = pathPoint(shape, a, from, to, i / 200.0);
    len += (q - prev).norm();
    prev = q;
  }
  return len;
}

task::Demonstration simulate(const Plan& plan, SplitMix64& rng, double jitter_m) {
  const auto& spec = plan.spec;
  const size_t m = spec.entities.size();
  std::vector<Vector2d> pos(m);
  // Entities sharing a template position (cargo on its robot) keep sharing it.
  std::map<std::pair<double, double>, Vector2d> placed;
  for (size_t e = 0; e < m; ++e) {
    const Vector2d base = plan.layout.at(spec.entities[e].name);
    auto key = std::make_pair(base.x(), base.y());
    auto it = placed.find(key);
    if (it == placed.end()) {
      Vector2d p = base + Vector2d(rng.uniform(-1, 1), rng.uniform(-1, 1)) * plan.layout_jitter;
      p = p.cwiseMax(0.03).cwiseMin(kTableSize - 0.03);
      it = placed.emplace(key, p).first;
    }
    pos[e] = it->second;
  }

  task::Demonstration d;
  d.has_label_columns.assign(m, false);
  for (const auto& step : plan.steps)
    for (const auto& mv : step) d.has_label_columns[spec.entityIndex(mv.entity)] = true;

  const std::vector<task::Label> idle(m);
  auto emit = [&](const std::vector<task::Label>& labels) {
    d.t.push_back(static_cast<double>(d.t.size()) / kGeneratorRateHz);
    d.positions.push_back(pos);
    d.labels.push_back(labels);
  };
  for (int i = 0; i < kIdleRowsBefore; ++i) emit(idle);

  for (size_t s = 0; s < plan.steps.size(); ++s) {
    const auto& step = plan.steps[s];
    struct Active {
      int entity;
      Vector2d from, to;
      Shape shape;
      double a;
    };
    std::vector<Active> moving;
    std::vector<task::Label> labels(m);
    double longest = 0;
    for (const auto& mv : step) {
      const int e = spec.entityIndex(mv.entity);
      labels[e].action = mv.action;
      if (mv.target.empty()) continue;
      labels[e].target = spec.entityIndex(mv.target);
      // Small per-demonstration variation of the shape: demonstrations are never identical.
      const double a = mv.shape.amplitude * (1 + 0.05 * rng.uniform(-1, 1));
      moving.push_back({e, pos[e], pos[labels[e].target], mv.shape, a});
      longest = std::max(longest, pathLength(mv.shape, a, pos[e], pos[labels[e].target]));
    }
    // All tokens of a step end together (step-synchronous demonstrations).
    const double duration = std::max(kMinStepDuration, longest / kSpeed);
    const int n = static_cast<int>(std::ceil(duration * kGeneratorRateHz));
    for (int j = 0; j <= n; ++j) {
      const double u = smoothstep(static_cast<double>(j) / n);
      for (const auto& mv : moving) pos[mv.entity] = pathPoint(mv.shape, mv.a, mv.from, mv.to, u);
      emit(labels);
    }
    const int gap = s + 1 < plan.steps.size() ? kIdleRowsBetween : kIdleRowsAfter;
    for (int i = 0; i < gap; ++i) emit(idle);
  }

  if (jitter_m > 0)
    for (auto& row : d.positions)
      for (auto& p : row) p += Vector2d(rng.normal(), rng.normal()) * jitter_m;
  return d;
}

/// One wrong label: the target of one token (its whole segment) names another entity.
void mislabel(task::Demonstration& d, const task::TaskSpec& spec, SplitMix64& rng) {
  d.analyze();
  std::vector<size_t> motions;
  for (size_t i = 0; i < d.segments.size(); ++i)
    if (d.segments[i].token.isMotion()) motions.push_back(i);
  if (motions.empty()) return;
  const task::Segment seg = d.segments[motions[rng.index(motions.size())]];
  std::vector<int> others;
  for (int e = 0; e < static_cast<int>(spec.entities.size()); ++e)
    if (e != seg.token.entity && e != seg.token.target) others.push_back(e);
  const int wrong = others[rng.index(others.size())];
  for (int r = seg.first_row; r <= seg.last_row; ++r) d.labels[r][seg.token.entity].target = wrong;
}

}  // namespace

std::vector<std::string> families() { return {"task1", "task2", "task3", "task4"}; }

task::TaskDir generate(const GeneratorOptions& o) {
  Plan plan;
  if (o.family == "task1") {
    plan = task1();
  } else if (o.family == "task2") {
    if (o.robots < 4 || o.robots > 11)
      throw Error("--robots " + std::to_string(o.robots) + " is out of range (task2 takes 4..11)");
    plan = task2(o.robots);
  } else if (o.family == "task3") {
    if (o.actions < 2 || o.actions > 4)
      throw Error("--actions " + std::to_string(o.actions) + " is out of range (task3 takes 2..4)");
    plan = task3(o.actions);
  } else if (o.family == "task4") {
    plan = task4();
  } else {
    throw Error("unknown task family '" + o.family + "' (expected task1, task2, task3 or task4)");
  }
  if (o.demos < 0) throw Error("the number of demonstrations must not be negative");
  if (o.jitter_m < 0 || !std::isfinite(o.jitter_m)) throw Error("jitter must be a non-negative number of metres");
  if (o.mislabel_fraction < 0 || o.mislabel_fraction > 1) throw Error("mislabel fraction must be in [0, 1]");
  plan.spec.actions_declared = true;

  task::TaskDir dir;
  dir.spec = plan.spec;
  SplitMix64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL);
  const int mislabelled = static_cast<int>(std::round(o.mislabel_fraction * o.demos));
  for (int i = 0; i < o.demos; ++i) {
    task::Demonstration d = simulate(plan, rng, o.jitter_m);
    if (i < mislabelled) mislabel(d, dir.spec, rng);
    d.analyze();
    dir.demos.push_back(std::move(d));
  }
  return dir;
}

}  // namespace ddace::tasks
