#include "ddace/tasks/rule_zoo.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <set>

#include "ddace/common/random.h"
#include "ddace/task/end_point.h"
#include "ddace/task/meeting_places.h"
#include "ddace/tasks/generators.h"

namespace ddace::tasks {

namespace {

using Eigen::Vector2d;
using task::EntityKind;

constexpr int kMaxAttempts = 200000;
/// Direct motion: draws per demonstration before a rule counts as one its bodies cannot
/// keep clear without bending around each other (e.g. a robot boxed in by those that met
/// at it, then leaving).
constexpr int kMaxDirectAttempts = 20000;
/// Direct motion: a path is an arc with this probability (else straight), its amplitude
/// uniform in [kArcMin, kArcMax] of the start-to-end distance, to either side.
constexpr double kArcFraction = 0.5, kArcMin = 0.1, kArcMax = 0.3;
constexpr int kMaxEntities = 10;

/// A referring expression: which entity of a set of candidates.
struct Selector {
  enum Mode { Nearest, Farthest, Axis } mode = Nearest;
  int rank = 0;          ///< 0: the first, 1: the second
  int axis = 0;          ///< Axis: 0 = x (left to right), 1 = y (front to back)
  bool reverse = false;  ///< Axis: right to left / back to front

  /// Sort key: the chosen entity has the rank-th smallest.
  double key(const Vector2d& p, const Vector2d& ref) const {
    switch (mode) {
      case Nearest:
        return (p - ref).norm();
      case Farthest:
        return -(p - ref).norm();
      case Axis:
        return reverse ? -p[axis] : p[axis];
    }
    return 0;
  }
  bool relative() const { return mode != Axis; }

  std::string adjective() const {
    static const char* ends[2][2] = {{"leftmost", "rightmost"}, {"frontmost", "backmost"}};
    static const char* from[2][2] = {{"from the left", "from the right"}, {"from the front", "from the back"}};
    const std::string nth = rank == 0 ? "" : "2nd ";
    switch (mode) {
      case Nearest:
        return nth + "nearest";
      case Farthest:
        return nth + "farthest";
      case Axis:
        return rank == 0 ? ends[axis][reverse] : std::string("2nd ") + from[axis][reverse];
    }
    return "";
  }
  /// "the robot nearest to B1", "the leftmost goal", "the 2nd from the left goal".
  std::string phrase(const std::string& kind, const std::string& ref) const {
    if (relative()) return "the " + kind + " " + adjective() + (mode == Nearest ? " to " : " from ") + ref;
    if (rank == 0) return "the " + adjective() + " " + kind;
    return "the " + kind + " " + adjective();
  }
  /// For matchings: "nearest", "farthest", "left-to-right".
  std::string order() const {
    static const char* names[2][2] = {{"left-to-right", "right-to-left"}, {"front-to-back", "back-to-front"}};
    return relative() ? adjective() : names[axis][reverse];
  }
};

/// The rule: a template and the referring expressions in its slots.
struct Rule {
  ZooRule info;
  Selector a, b, c;
  bool extra = false;  ///< fetch: the others go to the carrier; relay: the giver follows
  /// boxes (named rules only): the goals in name order each take the free box nearest to
  /// them ("the box nearer G1 goes to it, the other to G2") instead of the matching `b`.
  bool goals_in_turn = false;
};

/// One token: entity, action, target (entity indices).
struct Move {
  int entity;
  std::string action;
  int target;
};
using Steps = std::vector<std::vector<Move>>;

/// A selector over `candidates` for a draw: ranks beyond the first only with three or more.
Selector drawSelector(SplitMix64& rng, int candidates, bool relative_allowed = true, bool rank_allowed = true) {
  Selector s;
  const int mode = static_cast<int>(rng.index(relative_allowed ? 3 : 1));
  s.mode = relative_allowed ? static_cast<Selector::Mode>(mode) : Selector::Axis;
  if (s.mode == Selector::Axis) {
    s.axis = static_cast<int>(rng.index(2));
    s.reverse = rng.index(2) == 1;
  }
  if (rank_allowed && candidates >= 3 && rng.index(4) == 0) s.rank = 1;
  return s;
}

/// A selector for matchings (several at once): nearest / farthest greedy, or an axis order.
Selector drawMatching(SplitMix64& rng) {
  Selector s = drawSelector(rng, 0, true, false);
  return s;
}

int drawCount(SplitMix64& rng, int lo, int hi) {
  return lo + static_cast<int>(rng.index(static_cast<size_t>(hi - lo + 1)));
}

std::string counts(const ZooRule& r) {
  std::string s = "(" + std::to_string(r.robots) + " robots";
  if (r.objects) s += ", " + std::to_string(r.objects) + (r.objects == 1 ? " box" : " boxes");
  s += ", " + std::to_string(r.goals) + (r.goals == 1 ? " goal)" : " goals)");
  return s;
}

/// The rule in words (from its template, counts and selectors).
std::string words(const Rule& r) {
  const ZooRule& z = r.info;
  if (z.kind == "assign")
    return r.a.relative() ? "each robot to its " + r.a.adjective() + " free goal, all at once"
                          : "robots take goals in " + r.a.order() + " order, all at once";
  if (z.kind == "sequence")
    return "one robot per step, " + r.a.order() + ", each to its " + r.b.adjective() + " free goal";
  if (z.kind == "queue")
    return "robots take the slots Q1..Q" + std::to_string(z.goals) + " one per step, " +
           (r.a.relative() ? "the " + r.a.adjective() + (r.a.mode == Selector::Nearest ? " to" : " from") + " Q1 first"
                           : "in " + r.a.order() + " order");
  if (z.kind == "fetch")
    return r.a.phrase("robot", "B1") + " fetches B1 and carries it to " +
           (z.goals == 1 ? std::string("G1") : r.b.phrase("goal", "B1")) +
           (r.extra ? ", then the others go to the carrier" : "");
  if (z.kind == "relay")
    return r.a.phrase("robot", "B1") + " fetches B1 and hands it to " + r.b.phrase("teammate", "it") +
           ", who carries it to " + (z.goals == 1 ? std::string("G1") : r.c.phrase("goal", "the receiver")) +
           (r.extra ? ", then the giver follows the receiver" : "");
  if (z.kind == "boxes")
    return std::string("each box fetched by ") +
           (r.a.relative() ? "its " + r.a.adjective() + " free robot" : "the robots in " + r.a.order() + " order") +
           ", then carried to " +
           (r.goals_in_turn  ? "the goals in turn, G1 first, each taking the free box nearest to it"
            : r.b.relative() ? "its " + r.b.adjective() + " free goal"
                             : "the goals in " + r.b.order() + " order");
  return "the others meet at " + r.a.phrase("robot", "G1") + ", which then goes to " +
         (z.goals == 1 ? std::string("G1") : r.b.phrase("goal", "itself"));
}

void name(Rule& r) {
  r.info.name = r.info.kind + ": " + words(r) + " " + counts(r.info);
  r.info.family = "zoo:" + std::to_string(r.info.id);
}

Rule drawRule(uint64_t id) {
  SplitMix64 rng(id * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);
  static const char* kinds[] = {"assign", "sequence", "queue", "fetch", "relay", "boxes", "gather"};
  Rule r;
  r.info.id = id;
  r.info.kind = kinds[rng.index(7)];
  ZooRule& z = r.info;
  if (z.kind == "assign") {
    z.robots = drawCount(rng, 2, 5);
    z.goals = std::min(kMaxEntities - z.robots, z.robots + drawCount(rng, 0, 2));
    r.a = drawMatching(rng);
  } else if (z.kind == "sequence") {
    z.robots = drawCount(rng, 2, 4);
    z.goals = std::min(6, z.robots + drawCount(rng, 0, 2));
    r.a = drawSelector(rng, 0, false, false);
    r.b = drawSelector(rng, 0, true, false);
    if (!r.b.relative()) r.b.mode = Selector::Nearest;
  } else if (z.kind == "queue") {
    z.robots = drawCount(rng, 2, 4);
    z.goals = z.robots;
    r.a = drawMatching(rng);
  } else if (z.kind == "fetch") {
    z.robots = drawCount(rng, 2, 5);
    z.objects = 1;
    z.goals = drawCount(rng, 1, 4);
    r.a = drawSelector(rng, z.robots);
    r.b = drawSelector(rng, z.goals);
    r.extra = rng.index(2) == 1;
  } else if (z.kind == "relay") {
    z.robots = drawCount(rng, 3, 5);
    z.objects = 1;
    z.goals = drawCount(rng, 1, 3);
    r.a = drawSelector(rng, z.robots);
    r.b = drawSelector(rng, z.robots - 1);
    if (!r.b.relative()) r.b.mode = Selector::Nearest;  // the teammate is chosen relative to the giver
    r.c = drawSelector(rng, z.goals);
    r.extra = rng.index(2) == 1;
  } else if (z.kind == "boxes") {
    z.objects = drawCount(rng, 2, 3);
    z.robots = std::min(5, z.objects + drawCount(rng, 0, 1));
    z.goals = std::min(kMaxEntities - z.robots - z.objects, z.objects + drawCount(rng, 0, 1));
    r.a = drawMatching(rng);
    r.b = drawMatching(rng);
  } else {  // gather
    z.robots = drawCount(rng, 3, 6);
    z.goals = drawCount(rng, 1, 3);
    r.a = drawSelector(rng, z.robots);
    r.b = drawSelector(rng, z.goals);
  }
  name(r);
  return r;
}

/// The named rules (rule_zoo.h, namedZooRules): fixed rules of the grammar, some beyond
/// the drawn rules' counts.
struct Named {
  const char* key;
  Rule rule;
};

std::vector<Named> namedRules() {
  std::vector<Named> out;
  const auto add = [&](const char* key, const char* kind, int robots, int objects, int goals) -> Rule& {
    Rule r;
    r.info.kind = kind;
    r.info.robots = robots, r.info.objects = objects, r.info.goals = goals;
    out.push_back({key, r});
    return out.back().rule;
  };
  add("nearest-goals", "assign", 6, 0, 7).a.mode = Selector::Nearest;
  Rule& left_to_right = add("left-to-right", "assign", 3, 0, 3);
  left_to_right.a.mode = Selector::Axis, left_to_right.a.axis = 0;
  Rule& two_boxes = add("two-boxes", "boxes", 3, 2, 2);
  two_boxes.a.mode = Selector::Nearest, two_boxes.goals_in_turn = true;
  // Two carrier-load pairs in one step: each robot fetches its nearest box, then both carry
  // at once, the box nearer G1 to G1 and the other to G2.
  Rule& two_pairs = add("two-pairs", "boxes", 2, 2, 2);
  two_pairs.a.mode = Selector::Nearest, two_pairs.goals_in_turn = true;
  for (size_t k = 0; k < out.size(); ++k) {
    out[k].rule.info.id = kNamedZooRuleIds + k;
    name(out[k].rule);
    out[k].rule.info.family = std::string("zoo:") + out[k].key;
  }
  return out;
}

Rule ruleOf(uint64_t id) {
  if (id < kNamedZooRuleIds) return drawRule(id);
  const std::vector<Named> named = namedRules();
  if (id - kNamedZooRuleIds >= named.size()) throw Error("no named zoo rule has id " + std::to_string(id));
  return named[id - kNamedZooRuleIds].rule;
}

/// The task's entities: R1.., B1.., then G1.. (Q1.. for a queue's slots).
task::TaskSpec zooSpec(const ZooRule& z) {
  task::TaskSpec spec;
  // "zoo 17 assign: ...", "zoo two-boxes ...": the rule in words, not its counts (other
  // numbers of entities are the same task).
  spec.name = "zoo " + z.family.substr(4) + " " + z.name.substr(0, z.name.rfind(" ("));
  spec.actions = {"move"};
  if (z.objects) spec.actions.push_back("carry");
  spec.actions_declared = true;
  for (int i = 0; i < z.robots; ++i)
    spec.entities.push_back({"R" + std::to_string(i + 1), EntityKind::Robot, "hamster"});
  for (int i = 0; i < z.objects; ++i) spec.entities.push_back({"B" + std::to_string(i + 1), EntityKind::Object, "box"});
  const bool slots = z.kind == "queue";
  for (int i = 0; i < z.goals; ++i)
    spec.entities.push_back({(slots ? "Q" : "G") + std::to_string(i + 1), EntityKind::Goal, slots ? "slot" : ""});
  return spec;
}

/// Decides the steps of a rule on one start configuration, moving the entities as it goes
/// (a motion ends where the demonstration ends it: task::stepEndPositions).
class Decider {
 public:
  /// `without`: robots left out (lost): the rule picks among the others only.
  Decider(const task::TaskSpec& spec, const Rule& rule, const task::EndPointModel& end_points,
          std::vector<Vector2d> start, const std::vector<int>& without = {})
      : spec_(spec), rule_(rule), end_points_(end_points), pos_(std::move(start)) {
    const ZooRule& z = rule.info;
    for (int i = 0; i < z.robots; ++i)
      if (std::find(without.begin(), without.end(), i) == without.end()) robots_.push_back(i);
    for (int i = 0; i < z.objects; ++i) boxes_.push_back(z.robots + i);
    for (int i = 0; i < z.goals; ++i) goals_.push_back(z.robots + z.objects + i);
  }

  /// The steps, or false when a decision is a near tie or needs more entities than there
  /// are (`why` says which).
  bool decide(Steps& steps, ZooNoAnswer* why = nullptr) {
    const ZooRule& z = rule_.info;
    try {
      if (z.kind == "assign") {
        step({});
        for (auto [r, g] : match(robots_, goals_, rule_.a)) add(r, "move", g);
      } else if (z.kind == "sequence") {
        std::vector<int> free = goals_;
        for (int r : ordered(robots_, rule_.a, {0, 0})) {
          step({});
          const int g = pick(free, rule_.b, pos_[r]);
          free.erase(std::find(free.begin(), free.end(), g));
          add(r, "move", g);
          finish();
        }
      } else if (z.kind == "queue") {
        const std::vector<int> order = ordered(robots_, rule_.a, pos_[goals_[0]]);
        for (size_t k = 0; k < order.size(); ++k) {
          step({});
          add(order[k], "move", goals_[k]);
          finish();
        }
      } else if (z.kind == "fetch") {
        const int box = boxes_[0];
        const int a = pick(robots_, rule_.a, pos_[box]);
        step({}), add(a, "move", box), finish();
        const int g = goals_.size() == 1 ? goals_[0] : pick(goals_, rule_.b, pos_[box]);
        step({}), add(a, "carry", g), add(box, "carry", g), finish();
        if (rule_.extra) {
          step({});
          for (int r : robots_)
            if (r != a) add(r, "move", a);
        }
      } else if (z.kind == "relay") {
        const int box = boxes_[0];
        const int a = pick(robots_, rule_.a, pos_[box]);
        step({}), add(a, "move", box), finish();
        std::vector<int> mates = robots_;
        mates.erase(std::find(mates.begin(), mates.end(), a));
        const int b = pick(mates, rule_.b, pos_[a]);
        step({}), add(a, "carry", b), add(box, "carry", b), finish();
        const int g = goals_.size() == 1 ? goals_[0] : pick(goals_, rule_.c, pos_[b]);
        step({}), add(b, "carry", g), add(box, "carry", g), finish();
        if (rule_.extra) step({}), add(a, "move", b);
      } else if (z.kind == "boxes") {
        step({});
        std::vector<std::pair<int, int>> carriers;  // (box, robot)
        for (auto [box, r] : match(boxes_, robots_, rule_.a)) carriers.push_back({box, r}), add(r, "move", box);
        finish();
        step({});
        std::vector<std::pair<int, int>> delivered;  // (box, goal)
        if (rule_.goals_in_turn) {
          std::vector<int> free = boxes_;
          for (size_t k = 0; k < goals_.size() && !free.empty(); ++k) {
            const int box = pick(free, Selector{}, pos_[goals_[k]]);
            free.erase(std::find(free.begin(), free.end(), box));
            delivered.push_back({box, goals_[k]});
          }
        } else {
          delivered = match(boxes_, goals_, rule_.b);
        }
        for (auto [box, g] : delivered) {
          const int r = std::find_if(carriers.begin(), carriers.end(), [&](auto& c) { return c.first == box; })->second;
          add(r, "carry", g), add(box, "carry", g);
        }
      } else {  // gather
        const int a = pick(robots_, rule_.a, pos_[goals_[0]]);
        step({});
        for (int r : robots_)
          if (r != a) add(r, "move", a);
        finish();
        const int g = goals_.size() == 1 ? goals_[0] : pick(goals_, rule_.b, pos_[a]);
        step({}), add(a, "move", g);
      }
      finish();
    } catch (const Tie&) {
      if (why) *why = ZooNoAnswer::NearTie;
      return false;
    } catch (const TooFew&) {
      if (why) *why = ZooNoAnswer::TooFewEntities;
      return false;
    }
    steps = steps_;
    return true;
  }

 private:
  struct Tie {};
  struct TooFew {};  ///< a choice among fewer candidates than it needs (a robot left out)

  void step(std::vector<Move> moves) { steps_.push_back(std::move(moves)); }
  void add(int entity, const std::string& action, int target) { steps_.back().push_back({entity, action, target}); }
  /// Applies the last step's motions: each entity ends where the demonstration ends it.
  void finish() {
    if (steps_.empty() || applied_ == steps_.size()) return;
    std::vector<task::Token> tokens;
    for (const auto& m : steps_.back()) tokens.push_back({m.entity, m.action, m.target});
    pos_ = task::stepEndPositions(spec_, end_points_, tokens, pos_, kTable, -1, task::MeetingPlaces::InTokenOrder);
    applied_ = steps_.size();
  }

  /// `candidates` sorted by the selector's key; a tie (keys closer than the margin between
  /// the chosen rank and its neighbours) throws Tie.
  std::vector<int> ordered(std::vector<int> candidates, const Selector& s, const Vector2d& ref, bool all_ranks = true) {
    auto key = [&](int e) { return s.key(pos_[e], ref); };
    std::sort(candidates.begin(), candidates.end(), [&](int x, int y) { return key(x) < key(y); });
    for (size_t k = 0; k + 1 < candidates.size(); ++k)
      if ((all_ranks || k == static_cast<size_t>(s.rank) || k + 1 == static_cast<size_t>(s.rank)) &&
          key(candidates[k + 1]) - key(candidates[k]) < kSceneDecisionMargin)
        throw Tie{};
    return candidates;
  }
  int pick(const std::vector<int>& candidates, const Selector& s, const Vector2d& ref) {
    if (static_cast<int>(candidates.size()) <= s.rank) throw TooFew{};
    return ordered(candidates, s, ref, false)[s.rank];
  }
  /// Each of `left` to one of `right` (|left| <= |right|): greedy by the selector's key
  /// over all free pairs (each match beats every competing pair by the margin), or the
  /// k-th of `left` to the k-th of `right` in the selector's axis order.
  std::vector<std::pair<int, int>> match(const std::vector<int>& left, const std::vector<int>& right,
                                         const Selector& s) {
    std::vector<std::pair<int, int>> out;
    if (!s.relative()) {
      const std::vector<int> l = ordered(left, s, {0, 0}), r = ordered(right, s, {0, 0});
      for (size_t k = 0; k < l.size(); ++k) out.push_back({l[k], r[k]});
      return out;
    }
    std::set<int> used_l, used_r;
    auto key = [&](int x, int y) { return s.key(pos_[x], pos_[y]); };
    for (size_t round = 0; round < left.size(); ++round) {
      int bl = -1, br = -1;
      for (int x : left)
        for (int y : right)
          if (!used_l.count(x) && !used_r.count(y) && (bl < 0 || key(x, y) < key(bl, br))) bl = x, br = y;
      if (bl < 0) throw TooFew{};
      for (int x : left)
        for (int y : right)
          if (!used_l.count(x) && !used_r.count(y) && (x == bl) != (y == br) &&
              key(x, y) < key(bl, br) + kSceneDecisionMargin)
            throw Tie{};
      used_l.insert(bl), used_r.insert(br);
      out.push_back({bl, br});
    }
    return out;
  }

  const task::TaskSpec& spec_;
  const Rule& rule_;
  const task::EndPointModel& end_points_;
  std::vector<Vector2d> pos_;
  std::vector<int> robots_, boxes_, goals_;
  Steps steps_;
  size_t applied_ = 0;
};

/// The planned steps of `steps`: straight motions (the generators' motion, generators.h),
/// or with `direct` each motion straight or an arc, drawn from `rng`.
std::vector<PlannedStep> planned(const Steps& steps, bool direct, SplitMix64& rng) {
  std::vector<PlannedStep> out;
  for (const auto& step : steps) {
    out.emplace_back();
    for (const auto& mv : step) {
      PathShape shape;
      if (direct && rng.uniform(0, 1) < kArcFraction) {
        shape.kind = PathShape::Arc;
        shape.amplitude = (rng.index(2) ? 1 : -1) * rng.uniform(kArcMin, kArcMax);
      }
      out.back().push_back({{mv.entity, mv.action, mv.target}, shape, 0});
    }
  }
  return out;
}

/// Where motions end when a person stops `gap` metres short of contact with a robot or a
/// box: the footprints' end points (task/end_point.h) moved back by the gap, as the
/// classes of motions toward an obstacle (the zoo's robots share one footprint, its boxes
/// another). A load ends the gap short of an obstacle target, its carrier behind it.
task::EndPointModel gapEndPoints(const task::TaskSpec& spec, double gap) {
  task::EndPointModel m;
  if (gap == 0) return m;
  const auto first = [&](EntityKind kind) {
    for (size_t e = 0; e < spec.entities.size(); ++e)
      if (spec.entities[e].kind == kind) return static_cast<int>(e);
    return -1;
  };
  const int robot = first(EntityKind::Robot), box = first(EntityKind::Object);
  const std::string mover = task::toString(EntityKind::Robot);
  for (int target : {robot, box}) {
    if (target < 0 || !spec.footprint(target).obstacle) continue;
    const std::string to = std::string("->") + task::toString(spec.entities[static_cast<size_t>(target)].kind);
    const double contact = spec.contactDistance(robot, target);
    m.by_class[mover + to] = {Vector2d(-(contact + gap), 0), 1};
    if (box >= 0) {  // carrying a box: the box stops short, the carrier behind it
      const double load_end = spec.contactDistance(box, target) + gap;
      m.by_class[mover + "+load" + to] = {Vector2d(-(load_end + spec.contactDistance(robot, box)), 0), 1};
    }
  }
  return m;
}

}  // namespace

ZooRule zooRule(uint64_t id) {
  return ruleOf(id).info;
}

std::vector<ZooRule> namedZooRules() {
  std::vector<ZooRule> out;
  for (const Named& n : namedRules()) out.push_back(n.rule.info);
  return out;
}

std::vector<uint64_t> distinctZooRules(int count) {
  std::vector<uint64_t> ids;
  std::set<std::string> seen;
  for (uint64_t id = 0; static_cast<int>(ids.size()) < count; ++id)
    if (seen.insert(zooRule(id).name).second) ids.push_back(id);
  return ids;
}

std::string ZooMotion::suffix() const {
  if (!direct) return "";
  const long mm = std::lround(stop_gap_m * 1000);
  return mm == 0 ? "/direct" : "/direct-" + std::to_string(mm) + "mm";
}

std::string ZooMotion::words() const {
  if (!direct) return "paths bent around bodies, stops touching";
  const long mm = std::lround(stop_gap_m * 1000);
  return "direct paths, stops " + (mm == 0 ? std::string("touching") : std::to_string(mm) + " mm short");
}

std::vector<ZooMotion> directZooMotions() {
  return {{true, 0}, {true, 0.004}, {true, 0.01}};
}

bool parseZooFamily(const std::string& family, uint64_t& id, ZooMotion* motion) {
  const std::string prefix = "zoo:";
  if (family.rfind(prefix, 0) != 0) return false;
  std::string digits = family.substr(prefix.size());
  if (const size_t slash = digits.find('/'); slash != std::string::npos) {
    const std::string suffix = digits.substr(slash + 1);
    digits.resize(slash);
    const std::string usage = "family '" + family +
                              "': the motion of a zoo rule is /direct (stops touching) or /direct-<N>mm (N whole "
                              "millimetres, 0 to " +
                              std::to_string(std::lround(kMaxZooStopGapM * 1000)) + "), e.g. zoo:17/direct-4mm";
    ZooMotion m{true, 0};
    if (suffix != "direct") {
      const std::string head = "direct-", tail = "mm";
      const bool shaped = suffix.size() > head.size() + tail.size() && suffix.rfind(head, 0) == 0 &&
                          suffix.compare(suffix.size() - tail.size(), tail.size(), tail) == 0;
      const std::string mm = shaped ? suffix.substr(head.size(), suffix.size() - head.size() - tail.size()) : "";
      if (mm.empty() || mm.size() > 3 || !std::all_of(mm.begin(), mm.end(), ::isdigit)) throw Error(usage);
      m.stop_gap_m = std::stoi(mm) / 1000.0;
      if (m.stop_gap_m > kMaxZooStopGapM + 1e-12) throw Error(usage);
    }
    if (!motion)
      throw Error("family '" + family + "': a motion suffix is not taken here (the generators' motion only)");
    *motion = m;
  } else if (motion) {
    *motion = ZooMotion{};
  }
  for (const Named& n : namedRules())
    if (digits == n.key) {
      id = n.rule.info.id;
      return true;
    }
  if (digits.empty() || digits.size() > 18 || !std::all_of(digits.begin(), digits.end(), ::isdigit))
    throw Error("family '" + family +
                "': a zoo rule is zoo:<id>, the id a non-negative integer (e.g. zoo:17), or a named rule (" +
                [] {
                  std::string keys;
                  for (const Named& n : namedRules()) keys += (keys.empty() ? "zoo:" : ", zoo:") + std::string(n.key);
                  return keys;
                }() +
                ")");
  id = std::stoull(digits);
  return true;
}

std::vector<ZooKind> userKinds() {
  // The drawn rules: the first id (distinctZooRules order) stating the kind with at least 3 robots.
  return {
      {"six robots, seven goals, each robot to its own nearest goal", "zoo:nearest-goals"},
      {"the robot farthest from a box fetches it and carries it to a goal", "zoo:140"},
      {"three robots take three goals by left-to-right order on the table", "zoo:left-to-right"},
      {"a relay: the robot nearest the box fetches it, carries it to its own nearest teammate, who takes it to the "
       "goal",
       "zoo:87"},
      {"two boxes, each fetched by the robot nearest it; then the box nearer the goal goes to it, the other to a "
       "second "
       "goal",
       "zoo:two-boxes"},
      {"robots line up behind each other by their distance to a goal", "zoo:21"},
  };
}

OsrDistribution osrDistribution(const std::vector<double>& osr) {
  if (osr.empty()) throw Error("the OSR distribution of no rules");
  std::vector<double> v = osr;
  std::sort(v.begin(), v.end());
  const auto quantile = [&](double q) {  // linear between order statistics
    const double at = q * static_cast<double>(v.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(at)), hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (at - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  OsrDistribution d;
  d.rules = v.size();
  d.median = quantile(0.5);
  d.p10 = quantile(0.1);
  for (double x : v) d.mean += x / static_cast<double>(v.size());
  d.at_least_0_9 = static_cast<size_t>(std::count_if(v.begin(), v.end(), [](double x) { return x >= 0.9; }));
  return d;
}

bool BodiesComparison::goalsMet() const {
  return osr_ratio_median >= kBodiesOsrRatioMedian - 1e-9 && osr_ratio_p10 >= kBodiesOsrRatioP10 - 1e-9 &&
         collisions == 0 && fd_ratio_median <= kBodiesFdRatioMedian + 1e-9;
}

BodiesComparison compareBodies(const std::vector<std::pair<eval::Summary, eval::Summary>>& runs) {
  if (runs.empty()) throw Error("a comparison with bodies of no rules");
  std::vector<double> ideal, with, osr_ratio, fd_ratio;
  BodiesComparison c;
  c.rules = runs.size();
  double makespan = 0;
  for (const auto& [i, b] : runs) {
    ideal.push_back(i.osr), with.push_back(b.osr);
    if (i.osr > 0) osr_ratio.push_back(b.osr / i.osr);
    if (std::isfinite(i.fd) && std::isfinite(b.fd) && i.fd > 0) fd_ratio.push_back(b.fd / i.fd);
    c.collisions += b.collisions, c.trials_with_collision += b.trials_with_collision, c.trials += b.trials;
    if (std::isfinite(b.min_clearance_m) && !(b.min_clearance_m >= c.min_clearance_m))
      c.min_clearance_m = b.min_clearance_m;
    makespan += b.makespan_s;
  }
  c.ideal_osr_median = osrDistribution(ideal).median;
  c.bodies_osr_median = osrDistribution(with).median;
  if (!osr_ratio.empty()) {
    const OsrDistribution d = osrDistribution(osr_ratio);
    c.osr_ratio_median = d.median, c.osr_ratio_p10 = d.p10;
  }
  if (!fd_ratio.empty()) c.fd_ratio_median = osrDistribution(fd_ratio).median;
  c.makespan_s = makespan / static_cast<double>(runs.size());
  return c;
}

std::optional<std::vector<task::Step>> zooSteps(uint64_t rule_id, const task::TaskSpec& spec,
                                                const std::vector<Vector2d>& scene, const ZooMotion& motion,
                                                const std::vector<int>& without, ZooNoAnswer* why) {
  if (scene.size() != spec.entities.size())
    throw Error("a scene of " + std::to_string(scene.size()) + " positions for a task of " +
                std::to_string(spec.entities.size()) + " entities");
  Rule rule = ruleOf(rule_id);
  ZooRule& z = rule.info;
  z.robots = z.objects = z.goals = 0;
  for (const task::Entity& e : spec.entities)
    ++(e.kind == EntityKind::Robot ? z.robots : e.kind == EntityKind::Object ? z.objects : z.goals);
  Steps steps;
  for (int e : without)
    if (e < 0 || e >= static_cast<int>(spec.entities.size()) ||
        spec.entities[static_cast<size_t>(e)].kind != EntityKind::Robot)
      throw Error("only robots are left out of a zoo rule's team (entity " + std::to_string(e) + ")");
  if (!Decider(spec, rule, gapEndPoints(spec, motion.stop_gap_m), scene, without).decide(steps, why))
    return std::nullopt;
  std::vector<task::Step> out;
  for (const std::vector<Move>& moves : steps) {
    out.emplace_back();
    for (const Move& m : moves) out.back().tokens.push_back({m.entity, m.action, m.target});
  }
  return out;
}

bool zooRuleOfTask(const task::TaskSpec& spec, uint64_t& id, ZooMotion& motion) {
  const std::string prefix = "zoo ";
  if (spec.name.rfind(prefix, 0) != 0) return false;
  const std::string family = spec.name.substr(prefix.size(), spec.name.find(' ', prefix.size()) - prefix.size());
  try {
    if (!parseZooFamily("zoo:" + family, id, &motion)) return false;
    const std::string words = zooRule(id).name;
    return spec.name == prefix + family + " " + words.substr(0, words.rfind(" ("));
  } catch (const Error&) {
    return false;
  }
}

task::TaskDir generateZoo(uint64_t rule_id, int demos, uint64_t seed, const ZooMotion& motion,
                          const ZooCounts& counts) {
  if (demos < 0) throw Error("the number of demonstrations must not be negative");
  if (counts.robots < 0 || counts.objects < 0 || counts.goals < 0)
    throw Error("the numbers of entities must not be negative");
  if (!(motion.stop_gap_m >= 0 && motion.stop_gap_m <= kMaxZooStopGapM + 1e-12) ||
      (!motion.direct && motion.stop_gap_m != 0))
    throw Error("a zoo motion's stop gap must be 0 to " + std::to_string(kMaxZooStopGapM) +
                " m, and only for direct motion");
  Rule rule = ruleOf(rule_id);
  ZooRule& z = rule.info;
  const bool own_counts = (counts.robots == 0 || counts.robots == z.robots) &&
                          (counts.objects == 0 || counts.objects == z.objects) &&
                          (counts.goals == 0 || counts.goals == z.goals);
  if (counts.robots) z.robots = counts.robots;
  if (counts.objects) z.objects = counts.objects;
  if (counts.goals) z.goals = counts.goals;
  if (own_counts && rule_id < kNamedZooRuleIds && z.robots + z.objects + z.goals > kMaxEntities)
    throw Error("zoo rule " + std::to_string(rule_id) + " has more than " + std::to_string(kMaxEntities) + " entities");
  task::TaskDir dir;
  dir.spec = zooSpec(z);
  if (motion.direct)
    dir.spec.name = "zoo " + z.family.substr(4) + motion.suffix() + " " + z.name.substr(0, z.name.rfind(" ("));
  DemoMotion demo_motion;
  demo_motion.avoid = !motion.direct;
  demo_motion.push_loads = motion.direct;
  demo_motion.end_points = gapEndPoints(dir.spec, motion.stop_gap_m);
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ULL + 0x7A00C0DE5EEDULL + rule_id * 0xD1B54A32D192ED03ULL);
  const size_t m = dir.spec.entities.size();
  for (int i = 0; i < demos; ++i) {
    bool found = false;
    const int attempts = motion.direct ? kMaxDirectAttempts : kMaxAttempts;
    for (int attempt = 0; attempt < attempts && !found; ++attempt) {
      std::vector<Vector2d> start(m);
      const auto draw = [&] {
        return Vector2d(rng.uniform(kSceneBorder, kTableSize - kSceneBorder),
                        rng.uniform(kSceneBorder, kTableSize - kSceneBorder));
      };
      bool apart = true;
      if (rule_id < kNamedZooRuleIds && own_counts) {
        for (auto& p : start) p = draw();
        for (size_t x = 0; x < m && apart; ++x)
          for (size_t y = x + 1; y < m && apart; ++y) apart = (start[x] - start[y]).norm() >= kSceneMinSeparation;
      } else {
        // Named rules and other counts may have more entities than a whole draw keeps apart often enough
        // (13: about 1 in 3000): each entity is drawn again until apart from those before it.
        for (size_t x = 0; x < m && apart; ++x) {
          apart = false;
          for (int again = 0; again < 1000 && !apart; ++again) {
            start[x] = draw();
            apart = std::all_of(start.begin(), start.begin() + static_cast<long>(x),
                                [&](const Vector2d& p) { return (p - start[x]).norm() >= kSceneMinSeparation; });
          }
        }
      }
      if (!apart) continue;
      Steps steps;
      if (!Decider(dir.spec, rule, demo_motion.end_points, start).decide(steps)) continue;
      bool clear = true;
      task::Demonstration demo =
          simulateSteps(dir.spec, start, planned(steps, motion.direct, rng), demo_motion, &clear);
      if (!clear) continue;  // a body would pass through another: draw the scene again
      dir.demos.push_back(std::move(demo));
      found = true;
    }
    if (!found)
      throw Error("zoo rule " + std::to_string(rule_id) + motion.suffix() + " '" + z.name +
                  "': no unambiguous start configuration" + (motion.direct ? " whose bodies keep clear" : "") + " in " +
                  std::to_string(attempts) + " draws");
  }
  return dir;
}

}  // namespace ddace::tasks
