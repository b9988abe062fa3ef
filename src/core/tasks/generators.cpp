#include "ddace/tasks/generators.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <optional>

#include "ddace/common/random.h"
#include "ddace/task/end_point.h"
#include "micrometres.h"

namespace ddace::tasks {

namespace {

using Eigen::Vector2d;
using task::EntityKind;

using Shape = PathShape;

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

void addEntity(Plan& p, const std::string& name, EntityKind kind, const std::string& type, Vector2d where) {
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
  const std::vector<Vector2d> where = {{0.08, 0.15}, {0.08, 0.45}, {0.25, 0.30}, {0.50, 0.40},
                                       {0.30, 0.60}, {0.55, 0.75}, {0.80, 0.88}, {0.75, 0.55},
                                       {0.88, 0.30}, {0.45, 0.12}, {0.70, 0.15}};
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
  const Shape straight{Shape::Straight, 0}, approach{Shape::Arc, 0.15}, around{Shape::SCurve, 0.12};
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

// ---- the scene-dependent families: who acts (and where) follows from the start configuration

constexpr int kMaxSceneAttempts = 100000;

Vector2d tablePoint(SplitMix64& rng) {
  return {rng.uniform(kSceneBorder, kTableSize - kSceneBorder), rng.uniform(kSceneBorder, kTableSize - kSceneBorder)};
}

bool insideTable(const Vector2d& p) {
  return p.minCoeff() >= kSceneBorder && p.maxCoeff() <= kTableSize - kSceneBorder;
}

/// True when every pair of `points` is at least kSceneMinSeparation apart.
bool separated(const std::vector<Vector2d>& points) {
  for (size_t i = 0; i < points.size(); ++i)
    for (size_t j = i + 1; j < points.size(); ++j)
      if ((points[i] - points[j]).norm() < kSceneMinSeparation) return false;
  return true;
}

/// Index of the candidate nearest to `to` when it is nearer than every other by
/// kSceneDecisionMargin; -1 when the choice is ambiguous.
int clearlyNearest(const std::vector<Vector2d>& candidates, const Vector2d& to) {
  int best = -1;
  double d1 = 1e9, d2 = 1e9;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const double d = (candidates[i] - to).norm();
    if (d < d1) {
      d2 = d1;
      d1 = d;
      best = static_cast<int>(i);
    } else if (d < d2) {
      d2 = d;
    }
  }
  return d2 - d1 >= kSceneDecisionMargin ? best : -1;
}

/// A family whose steps are decided per demonstration by its start configuration.
struct SceneFamily {
  task::TaskSpec spec;
  /// Draws one start configuration (`layout` of the plan) and decides its steps;
  /// returns false to reject an ambiguous configuration (the caller draws again).
  std::function<bool(SplitMix64&, Plan&)> sample;
};

std::string robotName(int i) {
  return "R" + std::to_string(i + 1);
}

void addSceneEntity(task::TaskSpec& spec, const std::string& name, EntityKind kind, const std::string& type) {
  spec.entities.push_back({name, kind, type});
}

/// fetch: the robot nearest the box B1 fetches it (moves to it), then carries it to G1
/// (B1's own token in the same step); then the other robot follows the fetcher.
SceneFamily fetchFamily() {
  SceneFamily f;
  f.spec.name = "fetch_nearest_robot";
  f.spec.actions = {"move", "carry"};
  addSceneEntity(f.spec, "R1", EntityKind::Robot, "hamster");
  addSceneEntity(f.spec, "R2", EntityKind::Robot, "hamster");
  addSceneEntity(f.spec, "B1", EntityKind::Object, "box");
  addSceneEntity(f.spec, "G1", EntityKind::Goal, "");
  f.spec.goal_conditions = {{"B1", "G1", 0.05}};
  f.sample = [](SplitMix64& rng, Plan& p) {
    const std::vector<Vector2d> robots = {tablePoint(rng), tablePoint(rng)};
    const Vector2d box = tablePoint(rng), goal = tablePoint(rng);
    if (!separated({robots[0], robots[1], box, goal})) return false;
    const int fetcher = clearlyNearest(robots, box);
    if (fetcher < 0) return false;
    const std::string F = robotName(fetcher), O = robotName(1 - fetcher);
    p.layout = {{"R1", robots[0]}, {"R2", robots[1]}, {"B1", box}, {"G1", goal}};
    p.steps = {{{F, "move", "B1", {}}}, {{F, "carry", "G1", {}}, {"B1", "carry", "G1", {}}}, {{O, "move", F, {}}}};
    return true;
  };
  return f;
}

/// nearest_goal: R1..R3 and goals G1..G4; in one step every robot drives to its own
/// nearest free goal. "Free" is decided greedily by increasing distance: the closest
/// robot-goal pair is matched first, then the closest pair of the unmatched robots and
/// goals, and so on (one goal stays free). Each match beats every competing pair (same
/// robot or same goal) by kSceneDecisionMargin.
SceneFamily nearestGoalFamily() {
  constexpr int kRobots = 3, kGoals = 4;
  SceneFamily f;
  f.spec.name = "nearest_free_goal";
  f.spec.actions = {"move"};
  for (int i = 0; i < kRobots; ++i) addSceneEntity(f.spec, robotName(i), EntityKind::Robot, "hamster");
  for (int g = 0; g < kGoals; ++g) addSceneEntity(f.spec, "G" + std::to_string(g + 1), EntityKind::Goal, "");
  f.sample = [](SplitMix64& rng, Plan& p) {
    std::vector<Vector2d> all;
    for (int i = 0; i < kRobots + kGoals; ++i) all.push_back(tablePoint(rng));
    if (!separated(all)) return false;
    auto dist = [&](int r, int g) { return (all[r] - all[kRobots + g]).norm(); };
    std::vector<bool> robot_done(kRobots, false), goal_used(kGoals, false);
    std::vector<Move> step;
    for (int round = 0; round < kRobots; ++round) {
      int br = -1, bg = -1;
      for (int r = 0; r < kRobots; ++r)
        for (int g = 0; g < kGoals; ++g)
          if (!robot_done[r] && !goal_used[g] && (br < 0 || dist(r, g) < dist(br, bg))) br = r, bg = g;
      for (int r = 0; r < kRobots; ++r)
        for (int g = 0; g < kGoals; ++g)
          if (!robot_done[r] && !goal_used[g] && (r == br) != (g == bg) &&
              dist(r, g) < dist(br, bg) + kSceneDecisionMargin)
            return false;
      robot_done[br] = goal_used[bg] = true;
      step.push_back({robotName(br), "move", "G" + std::to_string(bg + 1), {}});
    }
    for (int i = 0; i < kRobots + kGoals; ++i) p.layout[p.spec.entities[i].name] = all[i];
    p.steps = {step};
    return true;
  };
  return f;
}

/// queue: R1..R3 line up in the slots Q1 (the head), Q2, Q3 (goals on a straight line,
/// kQueueSlotSpacing apart), one robot per step, in the order of their distance to Q1: the
/// nearest to Q1, then the next-nearest to Q2, the farthest to Q3.
SceneFamily queueFamily() {
  constexpr int kRobots = 3;
  SceneFamily f;
  f.spec.name = "queue_by_distance";
  f.spec.actions = {"move"};
  for (int i = 0; i < kRobots; ++i) addSceneEntity(f.spec, robotName(i), EntityKind::Robot, "hamster");
  for (int q = 0; q < kRobots; ++q) addSceneEntity(f.spec, "Q" + std::to_string(q + 1), EntityKind::Goal, "slot");
  f.sample = [](SplitMix64& rng, Plan& p) {
    std::vector<Vector2d> all;
    for (int i = 0; i < kRobots; ++i) all.push_back(tablePoint(rng));
    const Vector2d head = tablePoint(rng);
    const double angle = rng.uniform(0, 2 * M_PI);
    const Vector2d dir(std::cos(angle), std::sin(angle));
    for (int q = 0; q < kRobots; ++q) all.push_back(head + q * kQueueSlotSpacing * dir);
    for (const auto& a : all)
      if (!insideTable(a)) return false;
    if (!separated(all)) return false;
    std::vector<int> order(kRobots);
    for (int i = 0; i < kRobots; ++i) order[i] = i;
    auto d = [&](int r) { return (all[r] - head).norm(); };
    std::sort(order.begin(), order.end(), [&](int a, int b) { return d(a) < d(b); });
    for (int k = 0; k + 1 < kRobots; ++k)
      if (d(order[k + 1]) - d(order[k]) < kSceneDecisionMargin) return false;
    for (int i = 0; i < 2 * kRobots; ++i) p.layout[p.spec.entities[i].name] = all[i];
    p.steps.clear();
    for (int k = 0; k < kRobots; ++k)
      p.steps.push_back({{robotName(order[k]), "move", "Q" + std::to_string(k + 1), {}}});
    return true;
  };
  return f;
}

/// deliver: the robot nearest the box B1 fetches it and carries it to whichever of G1, G2
/// is nearer to the box; the other robot stays where it is.
SceneFamily deliverFamily() {
  SceneFamily f;
  f.spec.name = "deliver_to_nearest_goal";
  f.spec.actions = {"move", "carry"};
  addSceneEntity(f.spec, "R1", EntityKind::Robot, "hamster");
  addSceneEntity(f.spec, "R2", EntityKind::Robot, "hamster");
  addSceneEntity(f.spec, "B1", EntityKind::Object, "box");
  addSceneEntity(f.spec, "G1", EntityKind::Goal, "");
  addSceneEntity(f.spec, "G2", EntityKind::Goal, "");
  f.sample = [](SplitMix64& rng, Plan& p) {
    const std::vector<Vector2d> robots = {tablePoint(rng), tablePoint(rng)};
    const Vector2d box = tablePoint(rng);
    const std::vector<Vector2d> goals = {tablePoint(rng), tablePoint(rng)};
    if (!separated({robots[0], robots[1], box, goals[0], goals[1]})) return false;
    const int fetcher = clearlyNearest(robots, box), goal = clearlyNearest(goals, box);
    if (fetcher < 0 || goal < 0) return false;
    const std::string F = robotName(fetcher), G = "G" + std::to_string(goal + 1);
    p.layout = {{"R1", robots[0]}, {"R2", robots[1]}, {"B1", box}, {"G1", goals[0]}, {"G2", goals[1]}};
    p.steps = {{{F, "move", "B1", {}}}, {{F, "carry", G, {}}, {"B1", "carry", G, {}}}};
    return true;
  };
  return f;
}

const std::vector<std::string> kPaperFamilies = {"task1", "task2", "task3", "task4"};
const std::vector<std::string> kSceneFamilies = {"fetch", "nearest_goal", "queue", "deliver"};

SceneFamily sceneFamily(const std::string& name) {
  if (name == "fetch") return fetchFamily();
  if (name == "nearest_goal") return nearestGoalFamily();
  if (name == "queue") return queueFamily();
  return deliverFamily();
}

/// One start configuration of `family` and its steps, drawn until unambiguous.
Plan sampleScene(const SceneFamily& family, SplitMix64& rng) {
  for (int attempt = 0; attempt < kMaxSceneAttempts; ++attempt) {
    Plan p;
    p.spec = family.spec;
    p.layout_jitter = 0;  // the layout is the drawn configuration itself
    if (family.sample(rng, p)) return p;
  }
  throw Error("family '" + family.spec.name + "': no unambiguous start configuration in " +
              std::to_string(kMaxSceneAttempts) + " draws");
}

using detail::micrometres;

/// One demonstration of `plan`. Onset jitter delays each token's label (not its motion)
/// by a whole number of rows, drawn from `onset_rng` in [0, onset_jitter_s) seconds.
task::Demonstration simulate(const Plan& plan, SplitMix64& rng, double jitter_m, double onset_jitter_s,
                             SplitMix64& onset_rng) {
  const auto& spec = plan.spec;
  const size_t m = spec.entities.size();
  std::vector<Vector2d> pos(m);
  // Entities sharing a template position (cargo on its robot) start together: the later
  // one in front of the first, at their contact distance, toward its own first target.
  std::map<std::pair<double, double>, int> first_at;
  std::vector<int> rides_on(m, -1);
  for (size_t e = 0; e < m; ++e) {
    const Vector2d base = plan.layout.at(spec.entities[e].name);
    const auto key = std::make_pair(base.x(), base.y());
    if (auto it = first_at.find(key); it != first_at.end()) {
      rides_on[e] = it->second;
      continue;
    }
    Vector2d p = base;
    if (plan.layout_jitter > 0) p += Vector2d(rng.uniform(-1, 1), rng.uniform(-1, 1)) * plan.layout_jitter;
    pos[e] = p.cwiseMax(0.03).cwiseMin(kTableSize - 0.03);
    first_at.emplace(key, static_cast<int>(e));
  }
  for (size_t e = 0; e < m; ++e) {
    if (rides_on[e] < 0) continue;
    const Vector2d carrier = pos[static_cast<size_t>(rides_on[e])];
    Vector2d toward(1, 0);
    for (const auto& step : plan.steps) {
      const auto mv = std::find_if(step.begin(), step.end(), [&](const Move& x) {
        return x.entity == spec.entities[e].name && !x.target.empty();
      });
      if (mv == step.end()) continue;
      const Vector2d d = pos[static_cast<size_t>(spec.entityIndex(mv->target))] - carrier;
      if (d.norm() > 1e-9) toward = d.normalized();
      break;
    }
    pos[e] = carrier + spec.contactDistance(static_cast<int>(e), rides_on[e]) * toward;
  }

  std::vector<PlannedStep> steps;
  for (const auto& step : plan.steps) {
    steps.emplace_back();
    for (const auto& mv : step) {
      PlannedToken pt;
      pt.token.entity = spec.entityIndex(mv.entity);
      pt.token.action = mv.action;
      // floor: the label's lag never exceeds the drawn delay, so it begins before its step ends.
      if (onset_jitter_s > 0)
        pt.label_delay_rows = static_cast<int>(std::floor(onset_rng.uniform(0, onset_jitter_s) * kGeneratorRateHz));
      if (!mv.target.empty()) {
        pt.token.target = spec.entityIndex(mv.target);
        // Small per-demonstration variation of the shape: demonstrations are never identical.
        pt.shape = {mv.shape.kind, mv.shape.amplitude * (1 + 0.05 * rng.uniform(-1, 1))};
      }
      steps.back().push_back(pt);
    }
  }
  task::Demonstration d = simulateSteps(spec, pos, steps);
  if (jitter_m > 0) {
    for (auto& row : d.positions)
      for (auto& p : row) {
        p += Vector2d(rng.normal(), rng.normal()) * jitter_m;
        // Positions in whole micrometres, exactly the values a file holds.
        p = {micrometres(p.x()), micrometres(p.y())};
      }
  }
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

/// Two bodies cannot both stand on one goal: where goal conditions put several entities
/// "at" one target, the second ends at contact with the first (the end-point rule), so each
/// such condition's tolerance grows to the contact distance to the farthest-reaching other
/// entity plus the arrival radius (where the follower may stop), rounded up to whole
/// centimetres. A condition alone at its target keeps its tolerance.
void shareTargetsByBodies(task::TaskSpec& spec) {
  std::vector<double> grown;
  for (const auto& c : spec.goal_conditions) {
    double tolerance = c.tolerance;
    for (const auto& other : spec.goal_conditions)
      if (other.at == c.at && other.entity != c.entity) {
        const double reach = task::togetherDistance(spec, spec.entityIndex(c.entity), spec.entityIndex(other.entity));
        tolerance = std::max(tolerance, std::ceil(reach * 100 - 1e-9) / 100);
      }
    grown.push_back(tolerance);
  }
  for (size_t i = 0; i < grown.size(); ++i) spec.goal_conditions[i].tolerance = grown[i];
}

}  // namespace

std::vector<std::string> paperFamilies() {
  return kPaperFamilies;
}
std::vector<std::string> sceneFamilies() {
  return kSceneFamilies;
}
std::vector<std::string> allFamilies() {
  std::vector<std::string> all = kPaperFamilies;
  all.insert(all.end(), kSceneFamilies.begin(), kSceneFamilies.end());
  return all;
}
std::vector<std::string> families() {
  return kPaperFamilies;
}

task::TaskDir generate(const GeneratorOptions& o) {
  Plan plan;
  std::optional<SceneFamily> scene;
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
  } else if (std::find(kSceneFamilies.begin(), kSceneFamilies.end(), o.family) != kSceneFamilies.end()) {
    scene = sceneFamily(o.family);
    plan.spec = scene->spec;
  } else {
    std::string names;
    for (const auto& f : allFamilies()) names += (names.empty() ? "" : ", ") + f;
    throw Error("unknown task family '" + o.family + "' (expected one of " + names + ")");
  }
  if (o.demos < 0) throw Error("the number of demonstrations must not be negative");
  if (o.jitter_m < 0 || !std::isfinite(o.jitter_m)) throw Error("jitter must be a non-negative number of metres");
  if (o.mislabel_fraction < 0 || o.mislabel_fraction > 1) throw Error("mislabel fraction must be in [0, 1]");
  plan.spec.actions_declared = true;
  shareTargetsByBodies(plan.spec);
  // The labels of a step end together: a delay below the shortest step begins before they
  // end, so the late label joins its step.
  if (!(o.onset_jitter_s >= 0 && o.onset_jitter_s < kMinStepDurationS)) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "--onset-jitter %g is out of range: seconds in [0, %g), below the shortest step "
                  "so that every label begins before its step ends",
                  o.onset_jitter_s, kMinStepDurationS);
    throw Error(buf);
  }

  task::TaskDir dir;
  dir.spec = plan.spec;
  SplitMix64 rng(o.seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL);
  // Onset delays come from their own stream: the same seed gives the same scenes and
  // motions with and without --onset-jitter.
  SplitMix64 onset_rng(o.seed * 0x9E3779B97F4A7C15ULL + 0x3C6EF372FE94F82AULL);
  const int mislabelled = static_cast<int>(std::round(o.mislabel_fraction * o.demos));
  for (int i = 0; i < o.demos; ++i) {
    if (scene) plan = sampleScene(*scene, rng);
    task::Demonstration d = simulate(plan, rng, o.jitter_m, o.onset_jitter_s, onset_rng);
    if (i < mislabelled) mislabel(d, dir.spec, rng);
    d.analyze();
    dir.demos.push_back(std::move(d));
  }
  return dir;
}

}  // namespace ddace::tasks
