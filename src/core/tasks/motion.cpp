// The motion of generated demonstrations: where motions end, how loads ride, how paths
// keep bodies apart (generators.h, "the motion of a generated demonstration").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "ddace/common/error.h"
#include "ddace/task/end_point.h"
#include "ddace/task/meeting_places.h"
#include "ddace/tasks/generators.h"
#include "micrometres.h"

namespace ddace::tasks {

namespace {

using Eigen::Vector2d;

/// Collision checks sample a step at this many progress values (plus one).
constexpr int kCheckSamples = 200;
/// Distances within this of contact count as contact (floating point, not geometry).
constexpr double kContactSlack = 1e-9;

using detail::micrometres;

double smoothstep(double s) {
  return s * s * (3 - 2 * s);
}

double wrapAngle(double a) {
  return std::remainder(a, 2 * M_PI);
}

Vector2d rotated(const Vector2d& v, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
}

/// A mover's path: `shape` plus an extra arc `bend`, plus `align` times u^3 - u^2 (zero at
/// both ends and in slope at the start; it sets the final heading), all lateral, in the
/// frame from `from` to `to`.
struct Path {
  Vector2d from, to;
  PathShape shape;
  double bend = 0, align = 0;
  /// A hook (x and y in the path's frame) times u (1 - u)^4: zero at both ends and in slope
  /// at the end, it turns the start of the path (a robot leaving the bodies it touches); at
  /// most 0.082 of the hook, at u = 0.2.
  Vector2d hook = Vector2d::Zero();
  /// Progress along the path at time progress u is u^lag: a mover with lag > 1 falls
  /// behind and catches up at the end (it arrives after the movers before it).
  double lag = 1;
  /// A carrier first goes round its load, which stands, from where it touches it to `from`
  /// (behind the load as it will be pushed): an arc about `centre` from `round_start`
  /// turning `round_turn` radians, over the first `round_share` of the progress; the shape
  /// from `from` to `to` takes the rest.
  Vector2d centre = Vector2d::Zero(), round_start = Vector2d::Zero();
  double round_turn = 0, round_share = 0;

  double progress(double u) const { return lag == 1 ? u : std::pow(u, lag); }

  /// The shape in its own frame at progress u (x, y) and its derivative in u.
  void canonical(double u, Vector2d& c, Vector2d& dc) const {
    const double a = shape.amplitude;
    c = Vector2d::Zero(), dc = Vector2d::Zero();
    switch (shape.kind) {
      case PathShape::Straight:
        c = {u, 0}, dc = {1, 0};
        break;
      case PathShape::Arc:
        c = {u, a * std::sin(M_PI * u)}, dc = {1, a * M_PI * std::cos(M_PI * u)};
        break;
      case PathShape::SCurve:
        c = {u, a * std::sin(2 * M_PI * u)}, dc = {1, 2 * M_PI * a * std::cos(2 * M_PI * u)};
        break;
      case PathShape::Spiral: {
        // A loop and a half whose radius swells and vanishes: a spiral-like path.
        const double r = a * std::sin(M_PI * u), dr = a * M_PI * std::cos(M_PI * u), th = 3 * M_PI * u;
        c = {u + r * std::sin(th), r * (1 - std::cos(th))};
        dc = {1 + dr * std::sin(th) + 3 * M_PI * r * std::cos(th),
              dr * (1 - std::cos(th)) + 3 * M_PI * r * std::sin(th)};
        break;
      }
    }
    c.y() += bend * std::sin(M_PI * u) + align * (u * u * u - u * u);
    dc.y() += bend * M_PI * std::cos(M_PI * u) + align * (3 * u * u - 2 * u);
    const double v = 1 - u;
    c += hook * (u * v * v * v * v);
    dc += hook * (v * v * v * v - 4 * u * v * v * v);
  }
  /// Turns the start of the path `angle` radians from where it heads without a hook.
  void hookStart(double angle) {
    hook = Vector2d::Zero();
    if (angle == 0) return;
    Vector2d c = Vector2d::Zero(), dc = Vector2d::Zero();
    canonical(0, c, dc);
    hook = rotated(dc, angle) - dc;
  }
  /// The path's direction (d position / d progress, table frame) at time progress u, on
  /// its shape (a path that goes round a load first has no swinging rider).
  Vector2d tangent(double u) const {
    Vector2d c = Vector2d::Zero(), dc = Vector2d::Zero();
    canonical(progress(u), c, dc);
    const Vector2d d = to - from, perp(-d.y(), d.x());
    return dc.x() * d + dc.y() * perp;
  }
  /// Whether at time progress u the mover is still going round its load.
  bool goingRound(double u) const { return progress(u) < round_share; }
  /// Where the mover is at time progress u.
  Vector2d at(double u) const {
    const double s = progress(u);
    if (s < round_share) {
      const double f = s / round_share;
      const Vector2d r0 = round_start - centre, r1 = from - centre;
      const double radius = r0.norm() + (r1.norm() - r0.norm()) * f;
      const double angle = std::atan2(r0.y(), r0.x()) + round_turn * f;
      return centre + radius * Vector2d(std::cos(angle), std::sin(angle));
    }
    Vector2d c = Vector2d::Zero(), dc = Vector2d::Zero();
    canonical(round_share == 0 ? s : (s - round_share) / (1 - round_share), c, dc);
    const Vector2d d = to - from, perp(-d.y(), d.x());
    return from + c.x() * d + c.y() * perp;
  }
  /// Goes round `around` from round_start to `from` first, turning the short way or the
  /// long way round; its share of the progress is its share of the length.
  void goRound(const Vector2d& around, bool long_way) {
    centre = around, round_share = 0;
    const Vector2d r0 = round_start - around, r1 = from - around;
    round_turn = wrapAngle(std::atan2(r1.y(), r1.x()) - std::atan2(r0.y(), r0.x()));
    if (long_way) round_turn -= std::copysign(2 * M_PI, round_turn);
    const double round = std::abs(round_turn) * (r0.norm() + r1.norm()) / 2 + std::abs(r1.norm() - r0.norm());
    if (round < 1e-6) return;
    const double shaped = length();
    round_share = round / (round + shaped);
  }
  /// Makes the path end heading along `heading` (a carrier toward its load's end): the
  /// final slope in its frame is tan of the angle from the chord to `heading`.
  void alignEnd(const Vector2d& heading) {
    align = 0;
    const Vector2d d = to - from;
    if (d.norm() < task::kMinApproachM || heading.norm() == 0) return;
    const double beta = std::atan2(d.x() * heading.y() - d.y() * heading.x(), d.dot(heading));
    const double limit = 75 * M_PI / 180;  // a steeper turn would loop: keep the nearest heading
    Vector2d c = Vector2d::Zero(), dc = Vector2d::Zero();
    canonical(1, c, dc);
    align = std::tan(std::clamp(beta, -limit, limit)) * dc.x() - dc.y();
  }
  double length() const {
    double len = 0;
    Vector2d prev = from;
    for (int i = 1; i <= 200; ++i) {
      const Vector2d q = at(i / 200.0);
      len += (q - prev).norm();
      prev = q;
    }
    return len;
  }
};

/// A carried load. Pushed (DemoMotion::push_loads): it moves only as its carrier pushes
/// it, standing while the carrier goes round it to the side it is pushed from, then moving
/// with the carrier at the offset it ends at (never further than its pusher, nor turning
/// about it). Else it swings round to its carrier's front over the first kLoadSwingFraction
/// of the carry and rides there.
struct Rider {
  int load = -1;
  bool pushed = false;
  bool long_way = false;                ///< swing (go round the load) the long way round
  Vector2d start = Vector2d::Zero();    ///< where the load stands at the start of the step
  Vector2d offset = Vector2d::Zero();   ///< pushed: load - carrier while it is pushed (as at the end)
  Vector2d offset0 = Vector2d::Zero();  ///< load - carrier at the start of the step
  double contact = 0;                   ///< their contact distance

  Vector2d at(const Path& carrier, double u) const {
    if (pushed) return carrier.goingRound(u) ? start : Vector2d(carrier.at(u) + offset);
    const Vector2d c = carrier.at(u);
    const double r0 = offset0.norm(), a0 = std::atan2(offset0.y(), offset0.x());
    const Vector2d t0 = carrier.tangent(0), t = carrier.tangent(u);
    // A carrier that does not move keeps its load where it is.
    if (t0.norm() < 1e-12 || t.norm() < 1e-12) return c + offset0;
    const double h0 = std::atan2(t0.y(), t0.x()), h = std::atan2(t.y(), t.x());
    const double w = smoothstep(std::min(1.0, carrier.progress(u) / kLoadSwingFraction));
    double turn = wrapAngle(a0 - h0);
    if (long_way) turn -= std::copysign(2 * M_PI, turn);
    const double r = r0 + (contact - r0) * w, a = h + (1 - w) * turn;
    return c + r * Vector2d(std::cos(a), std::sin(a));
  }
};

/// The step's tokens: who moves on their own (movers), who rides (loads), who stands.
struct StepRoles {
  std::vector<int> movers;   ///< token indices of motions not carried
  std::vector<int> load_of;  ///< [token] index of its carried load's token, or -1
  std::vector<bool> moving;  ///< [entity] moves in this step (mover or load)
};

StepRoles roles(const task::TaskSpec& spec, const std::vector<task::Token>& step, const std::vector<Vector2d>& at) {
  const size_t entities = at.size();
  StepRoles r;
  r.load_of.assign(step.size(), -1);
  r.moving.assign(entities, false);
  for (const task::Token& t : step)
    if (t.entity < 0 || static_cast<size_t>(t.entity) >= entities || t.target >= static_cast<int>(entities))
      throw Error("a planned token names an entity outside the " + std::to_string(entities) + " of task '" + spec.name +
                  "'");
  std::vector<bool> carried(step.size(), false);
  for (size_t i = 0; i < step.size(); ++i)
    if (step[i].isMotion() && (r.load_of[i] = task::ridingLoad(spec, step, i, at)) >= 0)
      carried[static_cast<size_t>(r.load_of[i])] = true;
  for (size_t i = 0; i < step.size(); ++i) {
    if (!step[i].isMotion() || carried[i]) continue;
    r.movers.push_back(static_cast<int>(i));
    r.moving[static_cast<size_t>(step[i].entity)] = true;
    if (r.load_of[i] >= 0) r.moving[static_cast<size_t>(step[static_cast<size_t>(r.load_of[i])].entity)] = true;
  }
  return r;
}

bool isObstacle(const task::TaskSpec& spec, int e) {
  return spec.footprint(e).obstacle;
}

/// How far the body of `e` at `p` is inside the table's edges (metres; < 0: over one).
double edgeGap(const task::TaskSpec& spec, int e, const Vector2d& p) {
  return std::min({p.x(), p.y(), kTableSize - p.x(), kTableSize - p.y()}) - spec.footprint(e).radius_m;
}

/// One way of shaping a mover's path to keep clear of the others.
struct Candidate {
  double bend = 0, hook = 0, lag = 1;
  bool long_way = false;
  double deviation = 0;  ///< how far the path moves from its shape, in start-to-end distances
};

/// Every combination of kAvoidBends, kAvoidHooks, kAvoidLags and the load's swing, the
/// least changed path first: by how far it moves from the shape (an arc b: |b|; a hook
/// turning the start by a: at most 0.164 |sin(a / 2)|), then by lag (timing only, the path
/// unchanged), then the swing; ties in the order of the lists.
const std::vector<Candidate>& candidates() {
  static const std::vector<Candidate> all = [] {
    std::vector<Candidate> c;
    for (bool long_way : {false, true})
      for (double hook : kAvoidHooks)
        for (double bend : kAvoidBends)
          for (double lag : kAvoidLags)
            c.push_back({bend, hook, lag, long_way, std::abs(bend) + 0.164 * std::abs(std::sin(hook / 2))});
    std::stable_sort(c.begin(), c.end(), [](const Candidate& a, const Candidate& b) {
      if (a.deviation != b.deviation) return a.deviation < b.deviation;
      if (a.lag != b.lag) return a.lag < b.lag;
      return a.long_way < b.long_way;
    });
    return c;
  }();
  return all;
}

/// A body whose path over a step is fixed: standing, or a mover (and its load) as chosen.
struct Body {
  int entity;
  int mover;  ///< index into StepPaths::paths, -1 standing
  int rider;  ///< index into StepPaths::riders for a load, -1 otherwise
};

/// The paths of one step's movers, each chosen in turn so that its body (and its load's)
/// keeps clear of the bodies already fixed: standing ones and the movers before it.
class StepPaths {
 public:
  StepPaths(const task::TaskSpec& spec, const std::vector<Vector2d>& pos, const StepRoles& r, bool push_loads)
      : spec_(spec), pos_(pos), push_loads_(push_loads) {
    for (size_t e = 0; e < pos.size(); ++e)
      if (!r.moving[e] && isObstacle(spec, static_cast<int>(e))) fixed_.push_back({static_cast<int>(e), -1, -1});
  }

  std::vector<Path> paths;
  std::vector<Rider> riders;  // [mover] (load -1: none)

  /// Adds entity e's path to `end` (its load, -1 for none, riding to `load_end`): the first
  /// free of the candidates, least changed first, else the one with the most clearance;
  /// without `avoid` the planned shape as it is. Returns whether the bodies keep clear.
  bool add(int e, const PathShape& shape, const Vector2d& end, int load, const Vector2d& load_end, bool avoid) {
    Rider rider;
    Vector2d from = pos_[static_cast<size_t>(e)];
    if (load >= 0) {
      rider.load = load;
      rider.pushed = push_loads_;
      rider.start = pos_[static_cast<size_t>(load)];
      rider.offset = load_end - end;
      rider.offset0 = rider.start - from;
      rider.contact = spec_.contactDistance(e, load);
      if (rider.pushed) from = rider.start - rider.offset;  // behind the load: the push starts there
    }
    const size_t index = paths.size();
    paths.push_back({from, end, shape});
    paths.back().round_start = pos_[static_cast<size_t>(e)];
    riders.push_back(rider);
    std::vector<Body> candidate = {{e, static_cast<int>(index), -1}};
    if (load >= 0) candidate.push_back({load, static_cast<int>(index), static_cast<int>(index)});
    const Vector2d load_offset = load >= 0 ? Vector2d(load_end - end) : Vector2d::Zero();
    bool clear = true;
    const Candidate* best = &candidates().front();
    if (avoid) {
      best = leastChangedFree(index, candidate, load_offset);
    } else {  // the planned shape as it is (candidates' first: unchanged)
      reshape(index, *best, load_offset);
      clear = clearance(candidate) >= -kContactSlack;
    }
    reshape(index, *best, load_offset);
    for (const Body& b : candidate) fixed_.push_back(b);
    return clear;
  }

 private:
  void reshape(size_t index, const Candidate& k, const Vector2d& load_offset) {
    Path& path = paths[index];
    Rider& rider = riders[index];
    path.lag = k.lag;
    path.bend = k.bend;
    path.round_share = 0;
    if (rider.load >= 0) path.alignEnd(load_offset);
    path.hookStart(k.hook);
    rider.long_way = k.long_way;
    if (rider.pushed) path.goRound(rider.start, k.long_way);
  }

  /// The first free candidate; of the equally small changes (its mirror image), the one with
  /// the most clearance: the side a path turns to follows the layout, not the order of a
  /// list. None free: the one with the most clearance.
  const Candidate* leastChangedFree(size_t index, const std::vector<Body>& candidate, const Vector2d& load_offset) {
    const auto& all = candidates();
    const bool carries = riders[index].load >= 0;
    const Candidate* best = &all.front();
    double best_clearance = -std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < all.size(); ++i) {
      const Candidate& k = all[i];
      if (k.long_way && !carries) continue;
      reshape(index, k, load_offset);
      const double c = clearance(candidate);
      if (c > best_clearance + 1e-12) best_clearance = c, best = &k;
      if (c < -kContactSlack) continue;
      for (size_t j = i + 1; j < all.size() && all[j].deviation == k.deviation && all[j].lag == k.lag; ++j) {
        if (all[j].long_way && !carries) continue;
        reshape(index, all[j], load_offset);
        const double cj = clearance(candidate);
        if (cj > best_clearance + 1e-12) best_clearance = cj, best = &all[j];
      }
      break;
    }
    return best;
  }

  Vector2d where(const Body& b, double u) const {
    if (b.mover < 0) return pos_[static_cast<size_t>(b.entity)];
    if (b.rider >= 0) return riders[static_cast<size_t>(b.rider)].at(paths[static_cast<size_t>(b.mover)], u);
    return paths[static_cast<size_t>(b.mover)].at(u);
  }

  /// The least clearance of `candidate` bodies against the fixed ones over the step:
  /// distance less contact, measured from no closer than the pair starts or ends.
  double clearance(const std::vector<Body>& candidate) const {
    double worst = std::numeric_limits<double>::infinity();
    for (const Body& a : candidate) {
      // Its body stays on the table.
      const double g0 = edgeGap(spec_, a.entity, where(a, 0)), g1 = edgeGap(spec_, a.entity, where(a, 1));
      for (int k = 0; k <= kCheckSamples; ++k)
        worst = std::min(worst, edgeGap(spec_, a.entity, where(a, static_cast<double>(k) / kCheckSamples)) -
                                    std::min({0.0, g0, g1}));
      if (!isObstacle(spec_, a.entity)) continue;
      for (const Body& b : fixed_) {
        const double contact = spec_.contactDistance(a.entity, b.entity);
        const double d0 = (where(a, 0) - where(b, 0)).norm(), d1 = (where(a, 1) - where(b, 1)).norm();
        const double allowed = std::min({contact, d0, d1});
        for (int k = 0; k <= kCheckSamples; ++k) {
          const double u = static_cast<double>(k) / kCheckSamples;
          worst = std::min(worst, (where(a, u) - where(b, u)).norm() - allowed);
        }
      }
    }
    return worst;
  }

  const task::TaskSpec& spec_;
  const std::vector<Vector2d>& pos_;
  bool push_loads_;
  std::vector<Body> fixed_;
};

/// The rows of a demonstration being written: positions in micrometres at the generator's rate.
struct Rows {
  task::Demonstration& d;
  const std::vector<Vector2d>& pos;
  void emit(const std::vector<task::Label>& labels) {
    d.t.push_back(static_cast<double>(d.t.size()) / kGeneratorRateHz);
    std::vector<Vector2d> row(pos.size());
    for (size_t e = 0; e < pos.size(); ++e) row[e] = {micrometres(pos[e].x()), micrometres(pos[e].y())};
    d.positions.push_back(row);
    d.labels.push_back(labels);
  }
};

/// Moves the step's bodies along `paths` to `ends`, one row per generator tick; all tokens
/// of a step end together (step-synchronous demonstrations), each labelled from its delay on.
void emitStep(const PlannedStep& step, const std::vector<task::Token>& tokens, const StepRoles& r, const StepPaths& sp,
              const std::vector<Vector2d>& ends, std::vector<Vector2d>& pos, Rows& rows) {
  const size_t m = pos.size();
  double longest = 0;
  for (const Path& p : sp.paths) longest = std::max(longest, p.length());
  const double duration = std::max(kMinStepDurationS, longest / kGeneratorSpeed);
  const int n = static_cast<int>(std::ceil(duration * kGeneratorRateHz));
  std::vector<task::Label> labels(m);
  for (const auto& pt : step) labels[static_cast<size_t>(pt.token.entity)] = {pt.token.action, pt.token.target};
  std::vector<task::Label> row_labels(m);
  for (int j = 0; j <= n; ++j) {
    const double u = j == n ? 1.0 : smoothstep(static_cast<double>(j) / n);
    for (size_t k = 0; k < sp.paths.size(); ++k) {
      const int e = tokens[static_cast<size_t>(r.movers[k])].entity;
      pos[static_cast<size_t>(e)] = j == n ? ends[static_cast<size_t>(e)] : sp.paths[k].at(u);
      if (sp.riders[k].load >= 0)
        pos[static_cast<size_t>(sp.riders[k].load)] =
            j == n ? ends[static_cast<size_t>(sp.riders[k].load)] : sp.riders[k].at(sp.paths[k], u);
    }
    for (size_t e = 0; e < m; ++e) row_labels[e] = task::Label{};
    for (const auto& pt : step)
      if (j >= pt.label_delay_rows)
        row_labels[static_cast<size_t>(pt.token.entity)] = labels[static_cast<size_t>(pt.token.entity)];
    rows.emit(row_labels);
  }
}

}  // namespace

task::Demonstration simulateSteps(const task::TaskSpec& spec, const std::vector<Vector2d>& start,
                                  const std::vector<PlannedStep>& steps, const DemoMotion& motion, bool* bodies_clear) {
  if (bodies_clear) *bodies_clear = true;
  const size_t m = spec.entities.size();
  if (start.size() != m)
    throw Error("a start configuration of " + std::to_string(start.size()) + " positions for the " + std::to_string(m) +
                " entities of task '" + spec.name + "'");
  std::vector<Vector2d> pos = start;
  task::Demonstration d;
  d.has_label_columns.assign(m, false);
  for (const auto& step : steps)
    for (const auto& pt : step)
      if (pt.token.entity >= 0 && static_cast<size_t>(pt.token.entity) < m)
        d.has_label_columns[static_cast<size_t>(pt.token.entity)] = true;
  Rows rows{d, pos};
  const std::vector<task::Label> idle(m);
  for (int i = 0; i < kIdleRowsBefore; ++i) rows.emit(idle);
  for (size_t s = 0; s < steps.size(); ++s) {
    std::vector<task::Token> tokens;
    for (const auto& pt : steps[s]) tokens.push_back(pt.token);
    const std::vector<Vector2d> ends =
        task::stepEndPositions(spec, motion.end_points, tokens, pos, kTable, -1, task::MeetingPlaces::InTokenOrder);
    const StepRoles r = roles(spec, tokens, pos);
    StepPaths sp(spec, pos, r, motion.push_loads);
    for (int i : r.movers) {
      const PlannedToken& pt = steps[s][static_cast<size_t>(i)];
      const int e = pt.token.entity;
      const int load_token = r.load_of[static_cast<size_t>(i)];
      const int load = load_token >= 0 ? tokens[static_cast<size_t>(load_token)].entity : -1;
      const Vector2d load_end = load >= 0 ? ends[static_cast<size_t>(load)] : Vector2d::Zero();
      const bool clear = sp.add(e, pt.shape, ends[static_cast<size_t>(e)], load, load_end, motion.avoid);
      if (bodies_clear && !clear) *bodies_clear = false;
    }
    emitStep(steps[s], tokens, r, sp, ends, pos, rows);
    const int gap = s + 1 < steps.size() ? kIdleRowsBetween : kIdleRowsAfter;
    for (int i = 0; i < gap; ++i) rows.emit(idle);
  }
  d.analyze();
  return d;
}

}  // namespace ddace::tasks
