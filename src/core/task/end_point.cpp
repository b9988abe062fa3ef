#include "ddace/task/end_point.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "ddace/common/error.h"
#include "ddace/task/meeting_places.h"

namespace ddace::task {

namespace {

using Eigen::Vector2d;

/// The approach frame's x axis: the unit vector from `start` toward `target` (zero when
/// they are closer than kMinApproachM).
Vector2d approach(const Vector2d& start, const Vector2d& target) {
  const Vector2d d = target - start;
  const double n = d.norm();
  return n < kMinApproachM ? Vector2d::Zero() : Vector2d(d / n);
}

/// The length of the shortest way from `a` to `b` that keeps out of the disc of radius `r`
/// about `c` (both at least `r` from it): straight where the segment passes it, else along
/// a tangent from each and round the disc's edge between them.
double wayRound(const Vector2d& a, const Vector2d& b, const Vector2d& c, double r) {
  const double da = (a - c).norm(), db = (b - c).norm();
  if (da < kMinApproachM || db < kMinApproachM) return (a - b).norm();
  const double angle = std::acos(std::clamp((a - c).dot(b - c) / (da * db), -1.0, 1.0));
  const double ta = std::acos(std::min(1.0, r / da)), tb = std::acos(std::min(1.0, r / db));
  if (angle <= ta + tb) return (a - b).norm();
  return std::sqrt(std::max(0.0, da * da - r * r)) + std::sqrt(std::max(0.0, db * db - r * r)) + r * (angle - ta - tb);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// The median of `offsets` in polar form: the median distance from the target along the
/// median side. Where demonstrated ends lie round the target at several sides, a
/// component-wise median would fall nearer the target than any demonstration stopped (or
/// farther); the side is measured from behind the target as the mover approaches (-x),
/// where ends lie, so it does not wrap.
EndOffset medianOffset(const std::vector<Vector2d>& offsets) {
  std::vector<double> distance, side;
  for (const auto& o : offsets) distance.push_back(o.norm()), side.push_back(std::atan2(o.y(), -o.x()));
  const double r = median(distance), a = median(side);
  return {Vector2d(-r * std::cos(a), r * std::sin(a)), static_cast<int>(offsets.size())};
}

}  // namespace

int carriedLoad(const TaskSpec& spec, const std::vector<Token>& step, size_t i) {
  const Token& t = step.at(i);
  if (!t.isMotion() || spec.entities.at(static_cast<size_t>(t.entity)).kind != EntityKind::Robot) return -1;
  for (size_t j = 0; j < step.size(); ++j)
    if (j != i && step[j].action == t.action && step[j].target == t.target &&
        spec.entities.at(static_cast<size_t>(step[j].entity)).kind == EntityKind::Object)
      return static_cast<int>(j);
  return -1;
}

std::string motionClass(const TaskSpec& spec, const std::vector<Token>& step, size_t i) {
  const Token& t = step.at(i);
  return std::string(toString(spec.entities.at(static_cast<size_t>(t.entity)).kind)) +
         (carriedLoad(spec, step, i) >= 0 ? "+load" : "") + "->" +
         toString(spec.entities.at(static_cast<size_t>(t.target)).kind);
}

namespace {

/// One demonstrated end: its offset, its key and the step it stands in.
struct DemonstratedEnd {
  Vector2d offset;
  std::string key;
  int step = 0;
};

/// How well grouping a class's ends by `group` predicts a held-out one: each end against the
/// median of the others of its group (too few others for a key's offset: of the whole
/// class's others, as endOffset() falls back), the distances summed (metres).
template <typename Group>
double heldOutError(const std::vector<DemonstratedEnd>& ends, const Group& group) {
  double total = 0;
  for (size_t k = 0; k < ends.size(); ++k) {
    std::vector<Vector2d> mates, others;
    for (size_t j = 0; j < ends.size(); ++j) {
      if (j == k) continue;
      others.push_back(ends[j].offset);
      if (group(ends[j]) == group(ends[k])) mates.push_back(ends[j].offset);
    }
    if (others.empty()) return 0;
    const std::vector<Vector2d>& from = static_cast<int>(mates.size()) >= kMinKeySegments ? mates : others;
    total += (medianOffset(from).offset - ends[k].offset).norm();
  }
  return total;
}

/// The class's ends by step when the steps predict held-out ends better than the keys do
/// (steps of fewer than kMinKeySegments ends left out); empty: keyed by name.
std::map<int, EndOffset> roleOffsets(const std::vector<DemonstratedEnd>& ends) {
  const auto key = [](const DemonstratedEnd& e) { return e.key; };
  const auto step = [](const DemonstratedEnd& e) { return std::to_string(e.step); };
  std::map<int, EndOffset> out;
  const double gain = (heldOutError(ends, key) - heldOutError(ends, step)) / static_cast<double>(ends.size());
  if (!(gain >= kMinRoleEndGainM)) return out;
  std::map<int, std::vector<Vector2d>> by_step;
  for (const DemonstratedEnd& e : ends) by_step[e.step].push_back(e.offset);
  for (const auto& [k, offsets] : by_step)
    if (static_cast<int>(offsets.size()) >= kMinKeySegments) out[k] = medianOffset(offsets);
  return out;
}

}  // namespace

EndPointModel learnEndPoints(const TaskSpec& spec, const std::vector<Demonstration>& demos) {
  std::map<std::string, std::vector<DemonstratedEnd>> classes;
  for (const Demonstration& d : demos) {
    for (const Segment& seg : d.segments) {
      if (!seg.token.isMotion() || seg.step >= static_cast<int>(d.steps.size()) ||
          seg.step >= static_cast<int>(d.snapshots.size()))
        continue;
      const std::vector<Vector2d>& decided = d.snapshots[static_cast<size_t>(seg.step)].positions;
      const Vector2d s = decided.at(static_cast<size_t>(seg.token.entity));
      const Vector2d p = decided.at(static_cast<size_t>(seg.token.target));
      const Vector2d u = approach(s, p);
      if (u.isZero()) continue;
      const Vector2d rel =
          d.positions.at(static_cast<size_t>(seg.last_row)).at(static_cast<size_t>(seg.token.entity)) - p;
      const Vector2d offset(rel.dot(u), rel.dot(Vector2d(-u.y(), u.x())));
      const std::vector<Token>& step = d.steps[static_cast<size_t>(seg.step)].tokens;
      const auto at = std::find(step.begin(), step.end(), seg.token);
      if (at == step.end()) continue;
      classes[motionClass(spec, step, static_cast<size_t>(at - step.begin()))].push_back(
          {offset, tokenKey(seg.token, spec), seg.step});
    }
  }
  EndPointModel m;
  std::map<std::string, std::vector<Vector2d>> keys;  // a key's ends, of any class
  for (const auto& [c, ends] : classes) {
    std::vector<Vector2d> all;
    for (const DemonstratedEnd& e : ends) keys[e.key].push_back(e.offset), all.push_back(e.offset);
    m.by_class[c] = medianOffset(all);
    std::map<int, EndOffset> roles = roleOffsets(ends);
    if (!roles.empty()) m.by_role[c] = std::move(roles);
  }
  for (const auto& [k, v] : keys) m.by_key[k] = medianOffset(v);
  return m;
}

namespace {

/// The learned offset the rule uses for `step[i]`, the key's or its class's (nullptr: none;
/// `by_class` says which).
const EndOffset* learnedOffset(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step,
                               size_t i, int step_index = -1, bool* by_class = nullptr) {
  const Token& t = step.at(i);
  if (by_class) *by_class = false;
  // A class keyed by role: its offset of the step, or of the nearest demonstrated one (the
  // earlier on a tie).
  if (auto r = model.by_role.find(motionClass(spec, step, i)); step_index >= 0 && r != model.by_role.end()) {
    const EndOffset* best = nullptr;
    int best_distance = 0;
    for (const auto& [k, e] : r->second)
      if (!best || std::abs(k - step_index) < best_distance) best = &e, best_distance = std::abs(k - step_index);
    if (best) return best;
  }
  if (auto k = model.by_key.find(tokenKey(t, spec)); k != model.by_key.end() && k->second.segments >= kMinKeySegments)
    return &k->second;
  if (by_class) *by_class = true;
  if (auto c = model.by_class.find(motionClass(spec, step, i)); c != model.by_class.end() && c->second.segments > 0)
    return &c->second;
  return nullptr;
}

}  // namespace

Vector2d endOffset(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i,
                   int step_index) {
  const Token& t = step.at(i);
  if (model.centres || !t.isMotion()) return Vector2d::Zero();
  if (const EndOffset* learned = learnedOffset(spec, model, step, i, step_index)) return learned->offset;
  // Nothing demonstrated: the bodies decide. Toward an obstacle, contact; onto a flat goal.
  const Footprint mover = spec.footprint(t.entity), target = spec.footprint(t.target);
  const int load = carriedLoad(spec, step, i);
  if (load < 0) return Vector2d(target.obstacle ? -(mover.radius_m + target.radius_m) : 0.0, 0.0);
  const Footprint carried = spec.footprint(step[static_cast<size_t>(load)].entity);
  const double load_end = target.obstacle ? carried.radius_m + target.radius_m : 0.0;
  return Vector2d(-(load_end + carried.radius_m + mover.radius_m), 0.0);
}

namespace {

// What an overlap means for the runs and whether to act: bodies are held to the footprints,
// so the runs end that much farther apart than the demonstrations did.
std::string overlapAdvice(const std::string& mover, const std::string& target, long mm) {
  return "ending at their contact (footprints stated too big?), " + std::to_string(mm) +
         " mm farther apart than demonstrated: if " + mover + " or " + target +
         " is smaller than task.yaml states, correct its radius; a body nudged on arrival or the camera's error "
         "shows the same and needs nothing";
}

}  // namespace

std::string StopGap::str() const {
  const long mm = std::lround(gap_m * 1000);
  std::string s =
      mover +
      (mm < 0 ? " stops " + std::to_string(-mm) + " mm inside " + target + "'s footprint"
              : " stops " + std::to_string(mm) + " mm from " + target) +
      " in the demonstrations (" + std::to_string(segments) + " stops" + (by_class ? ", its motion class's" : "") +
      "); footprints say 0 mm: " + (mm < 0 ? overlapAdvice(mover, target, -mm) : "using the demonstrated gap");
  return s;
}

std::vector<StopGap> stopGaps(const TaskSpec& spec, const EndPointModel& model,
                              const std::vector<Demonstration>& demos) {
  std::vector<StopGap> out;
  if (model.centres) return out;
  std::set<std::string> seen;
  for (const Demonstration& d : demos)
    for (const Step& step : d.steps)
      for (size_t i = 0; i < step.tokens.size(); ++i) {
        const Token& t = step.tokens[i];
        const int n = static_cast<int>(spec.entities.size());
        if (!t.isMotion() || t.entity < 0 || t.entity >= n || t.target < 0 || t.target >= n) continue;
        const std::string key = tokenKey(t, spec);
        if (!spec.footprint(t.entity).obstacle || !spec.footprint(t.target).obstacle ||
            carriedLoad(spec, step.tokens, i) >= 0 || !seen.insert(key).second)
          continue;
        bool by_class = false;
        const EndOffset* learned = learnedOffset(spec, model, step.tokens, i, -1, &by_class);
        if (!learned) continue;
        const double gap = learned->offset.norm() - spec.contactDistance(t.entity, t.target);
        if (std::lround(gap * 1000) == 0) continue;  // whole millimetres, as reported
        out.push_back({key, spec.entities[static_cast<size_t>(t.entity)].name,
                       spec.entities[static_cast<size_t>(t.target)].name, gap, learned->segments, by_class});
      }
  return out;
}

Vector2d endPointFrom(const Vector2d& start, const Vector2d& target, const Vector2d& offset) {
  const Vector2d u = approach(start, target);
  if (u.isZero()) return start;
  return target + offset.x() * u + offset.y() * Vector2d(-u.y(), u.x());
}

Vector2d endPoint(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i,
                  const std::vector<Vector2d>& decided, int step_index) {
  const Token& t = step.at(i);
  const auto n = static_cast<int>(decided.size());
  if (t.entity < 0 || t.entity >= n || t.target >= n)
    throw Error("end point of a token naming an entity outside the " + std::to_string(n) + " positions given");
  if (!t.isMotion()) return decided[static_cast<size_t>(t.entity)];
  return endPointFrom(decided[static_cast<size_t>(t.entity)], decided[static_cast<size_t>(t.target)],
                      endOffset(spec, model, step, i, step_index));
}

Vector2d segmentEndPoint(const TaskSpec& spec, const EndPointModel& model, const Demonstration& demo,
                         const Segment& segment) {
  const auto k = static_cast<size_t>(segment.step);
  if (segment.step < 0 || k >= demo.steps.size() || k >= demo.snapshots.size()) return demo.segmentGoal(segment);
  const std::vector<Token>& step = demo.steps[k].tokens;
  const auto at = std::find(step.begin(), step.end(), segment.token);
  if (at == step.end()) return demo.segmentGoal(segment);
  return endPoint(spec, model, step, static_cast<size_t>(at - step.begin()), demo.snapshots[k].positions, segment.step);
}

int ridingLoad(const TaskSpec& spec, const std::vector<Token>& step, size_t i, const std::vector<Vector2d>& at) {
  const auto n = static_cast<int>(at.size());
  // carriedLoad(step[k]) when it is at its carrier, else -1.
  const auto atCarrier = [&](size_t k) {
    const int load = carriedLoad(spec, step, k);
    if (load < 0) return -1;
    const int e = step[k].entity, l = step[static_cast<size_t>(load)].entity;
    if (e < 0 || e >= n || l < 0 || l >= n)
      throw Error("a token names an entity outside the " + std::to_string(n) + " positions given");
    return together(spec, e, at[static_cast<size_t>(e)], l, at[static_cast<size_t>(l)]) ? load : -1;
  };
  const int load = atCarrier(i);
  for (size_t k = 0; load >= 0 && k < i; ++k)  // a load of two carriers rides with the first
    if (step[k].isMotion() && atCarrier(k) == load) return -1;
  return load;
}

std::vector<Vector2d> stepEndPositions(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step,
                                       const std::vector<Vector2d>& decided,
                                       const std::optional<Eigen::AlignedBox2d>& table, int step_index) {
  return stepEndPositions(spec, model, step, decided, table, step_index, MeetingPlaces::ByLeastTravel);
}

namespace {

constexpr double kSlack = 1e-9;  // floating point, not geometry

Vector2d rotated(const Vector2d& v, double a) {
  return Vector2d(std::cos(a) * v.x() - std::sin(a) * v.y(), std::sin(a) * v.x() + std::cos(a) * v.y());
}

/// A mover's end and its riding load's (zero without one).
struct MoverEnd {
  Vector2d end, load_end;
};

/// The end positions of one step, placed mover by mover (stepEndPositions).
class StepEnds {
 public:
  StepEnds(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step,
           const std::vector<Vector2d>& decided, const std::optional<Eigen::AlignedBox2d>& table, int step_index)
      : spec_(spec),
        model_(model),
        step_(step),
        decided_(decided),
        table_(table),
        step_index_(step_index),
        ends_(decided) {
    const auto n = static_cast<int>(decided.size());
    for (const Token& t : step)
      if (t.entity < 0 || t.entity >= n || t.target >= n)
        throw Error("a token names an entity outside the " + std::to_string(n) + " positions given");
    findMovers();
  }

  /// Each mover's end: the rule's end point, else the nearest turn about its target that is
  /// free, else short of it on the way.
  void placeMovers() {
    for (size_t i : movers_) place(i);
  }

  /// Robots meeting at one body: who takes which place (task/meeting_places.h), pairs
  /// swapped while a swap shortens their travel round the body.
  void assignMeetingPlaces() {
    for (bool swapped = true; swapped;) {
      swapped = false;
      for (size_t a = 0; a < movers_.size(); ++a)
        for (size_t b = a + 1; b < movers_.size(); ++b) swapped |= swapIfShorter(movers_[a], movers_[b]);
    }
  }

  const std::vector<Vector2d>& ends() const { return ends_; }

 private:
  /// Who moves: the motions and the loads riding with them; the bodies standing are placed.
  void findMovers() {
    load_of_.assign(step_.size(), -1);
    std::vector<bool> rides(step_.size(), false), moving(decided_.size(), false);
    for (size_t i = 0; i < step_.size(); ++i)
      if (step_[i].isMotion() && (load_of_[i] = ridingLoad(spec_, step_, i, decided_)) >= 0)
        rides[static_cast<size_t>(load_of_[i])] = true;
    for (size_t i = 0; i < step_.size(); ++i) {
      if (!step_[i].isMotion() || rides[i]) continue;
      movers_.push_back(i);
      moving[static_cast<size_t>(step_[i].entity)] = true;
      if (load_of_[i] >= 0) moving[static_cast<size_t>(loadOf(i))] = true;
    }
    for (int e = 0; e < static_cast<int>(decided_.size()); ++e)
      if (!moving[static_cast<size_t>(e)] && obstacle(e)) placed_.push_back(e);
  }

  int loadOf(size_t i) const { return load_of_[i] >= 0 ? step_[static_cast<size_t>(load_of_[i])].entity : -1; }
  bool obstacle(int e) const { return spec_.footprint(e).obstacle; }
  const Vector2d& decided(int e) const { return decided_[static_cast<size_t>(e)]; }

  /// How far the body of e at p is inside the table's edges (metres; < 0: over one).
  double edgeGap(int e, const Vector2d& p) const {
    if (!table_) return std::numeric_limits<double>::infinity();
    const Vector2d lo = p - table_->min(), hi = table_->max() - p;
    return std::min({lo.x(), lo.y(), hi.x(), hi.y()}) - spec_.footprint(e).radius_m;
  }
  /// On the table, or no further over its edge than where the body was when decided.
  bool onTable(int e, const Vector2d& p) const { return edgeGap(e, p) >= std::min(0.0, edgeGap(e, decided(e))); }

  /// Free: on the table, and no closer than contact to a placed body (plus `gap` to any but
  /// the motion's target; the target as near as the rule's end, `reach`, where the
  /// demonstrations stop inside the footprints).
  bool free(int entity, const Vector2d& at, int partner, int target, double gap, double reach) const {
    if (!onTable(entity, at)) return false;
    if (!obstacle(entity)) return true;
    for (int b : placed_) {
      const double contact = spec_.contactDistance(entity, b);
      if (b != partner && (at - ends_[static_cast<size_t>(b)]).norm() <
                              (b == target ? std::min(contact, reach) : contact + gap) - kSlack)
        return false;
    }
    return true;
  }

  /// The rule's end of mover i and its load's. A gap wider than contact is kept; an end
  /// inside its target's footprint moves out to contact on its side (the footprints are what
  /// the safety filter and the collision judge hold bodies to), so a turn about the target
  /// keeps it touching the target.
  MoverEnd ruleEnd(size_t i) const {
    const Token& t = step_[i];
    const Vector2d start = decided(t.entity), target = decided(t.target);
    const int load = loadOf(i);
    Vector2d end = endPoint(spec_, model_, step_, i, decided_, step_index_);
    const double contact = spec_.contactDistance(t.entity, t.target);
    if (load < 0 && obstacle(t.target) && obstacle(t.entity) && (end - target).norm() < contact) {
      const Vector2d side = (end - target).norm() >= kMinApproachM ? end - target : start - target;
      if (side.norm() >= kMinApproachM) end = target + contact * side.normalized();
    }
    Vector2d load_end = Vector2d::Zero();
    if (load >= 0) {
      const Vector2d d = target - start;
      const Vector2d u =
          d.norm() < kMinApproachM ? Vector2d(decided(load) - start).normalized() : Vector2d(d.normalized());
      load_end = end + spec_.contactDistance(t.entity, load) * u;
    }
    return {end, load_end};
  }

  /// Mover i and its load fit at `at` (turned or shifted the same), keeping `gap` from bodies.
  bool fits(size_t i, const MoverEnd& at, const MoverEnd& rule, double gap) const {
    const Token& t = step_[i];
    const int load = loadOf(i);
    const Vector2d target = decided(t.target);
    const double reach = std::max((rule.end - target).norm(), spec_.contactDistance(t.entity, t.target));
    return free(t.entity, at.end, load, t.target, gap, reach) &&
           (load < 0 || free(load, at.load_end, t.entity, t.target, gap, (rule.load_end - target).norm()));
  }

  /// The rule's end point, else the nearest turn about the target that is free.
  std::optional<MoverEnd> turnedEnd(size_t i, const MoverEnd& rule) const {
    const Vector2d target = decided(step_[i].target);
    for (int k = 0; k * kEndTurnStepRad <= kMaxEndTurnRad + 1e-12; ++k)
      for (int sign : {1, -1}) {
        if (k == 0 && sign < 0) continue;
        const double angle = sign * k * kEndTurnStepRad;
        const MoverEnd turned{target + rotated(rule.end - target, angle),
                              target + rotated(rule.load_end - target, angle)};
        // A turned end keeps kEndTurnGapM from the bodies it turned away from: it touches
        // its target only (what it touches says where it went).
        if (fits(i, turned, rule, k == 0 ? 0.0 : kEndTurnGapM)) return turned;
      }
    return std::nullopt;
  }

  /// Onto a goal already taken (turning about its centre changes nothing): short of it, on
  /// the way, where the body first fits.
  std::optional<MoverEnd> backedOffEnd(size_t i, const MoverEnd& rule) const {
    const Vector2d back = rule.end - decided(step_[i].entity);
    for (double off = kBackOffStepM; off < back.norm(); off += kBackOffStepM) {
      const Vector2d shift = -off * back.normalized();
      const MoverEnd shifted{rule.end + shift, rule.load_end + shift};
      if (fits(i, shifted, rule, 0)) return shifted;
    }
    return std::nullopt;
  }

  void place(size_t i) {
    const MoverEnd rule = ruleEnd(i);
    std::optional<MoverEnd> found = turnedEnd(i, rule);
    if (!found) found = backedOffEnd(i, rule);
    const MoverEnd chosen = found.value_or(rule);
    const int entity = step_[i].entity, load = loadOf(i);
    ends_[static_cast<size_t>(entity)] = chosen.end;
    if (obstacle(entity)) placed_.push_back(entity);
    if (load >= 0) {
      ends_[static_cast<size_t>(load)] = chosen.load_end;
      if (obstacle(load)) placed_.push_back(load);
    }
  }

  /// Movers i and j go to one body, each carrying nothing, both of one size.
  bool meet(size_t i, size_t j) const {
    const int a = step_[i].entity, b = step_[j].entity;
    return step_[i].target == step_[j].target && obstacle(step_[i].target) && load_of_[i] < 0 && load_of_[j] < 0 &&
           obstacle(a) && obstacle(b) && spec_.footprint(a).radius_m == spec_.footprint(b).radius_m;
  }
  /// Mover i's way to `p` round its target's contact disc.
  double travel(size_t i, const Vector2d& p) const {
    const int e = step_[i].entity, t = step_[i].target;
    return wayRound(decided(e), p, decided(t), spec_.contactDistance(e, t));
  }
  bool swapIfShorter(size_t i, size_t j) {
    if (!meet(i, j)) return false;
    const int ei = step_[i].entity, ej = step_[j].entity;
    Vector2d &pi = ends_[static_cast<size_t>(ei)], &pj = ends_[static_cast<size_t>(ej)];
    if (!(travel(i, pj) + travel(j, pi) < travel(i, pi) + travel(j, pj) - kSlack && onTable(ei, pj) && onTable(ej, pi)))
      return false;
    std::swap(pi, pj);
    return true;
  }

  const TaskSpec& spec_;
  const EndPointModel& model_;
  const std::vector<Token>& step_;
  const std::vector<Vector2d>& decided_;
  const std::optional<Eigen::AlignedBox2d>& table_;
  const int step_index_;
  std::vector<Vector2d> ends_;
  std::vector<int> load_of_;    ///< per token, the token of the load riding with it, or -1
  std::vector<size_t> movers_;  ///< tokens that move a body of their own
  std::vector<int> placed_;     ///< bodies an end must keep clear of: standing, then ends placed
};

}  // namespace

std::vector<Vector2d> stepEndPositions(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step,
                                       const std::vector<Vector2d>& decided,
                                       const std::optional<Eigen::AlignedBox2d>& table, int step_index,
                                       MeetingPlaces meetings) {
  StepEnds ends(spec, model, step, decided, table, step_index);
  ends.placeMovers();
  if (meetings == MeetingPlaces::ByLeastTravel) ends.assignMeetingPlaces();
  return ends.ends();
}

}  // namespace ddace::task
