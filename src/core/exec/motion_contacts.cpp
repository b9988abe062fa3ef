#include "ddace/exec/motion_contacts.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "ddace/common/error.h"
#include "ddace/task/body_geometry.h"

namespace ddace::exec {

namespace {
std::pair<int, int> ordered(int a, int b) {
  return {std::min(a, b), std::max(a, b)};
}

/// Whether a body of `radius_m` at `place` lies on the planned `way` of a body of
/// `mover_radius_m` (empty: unknown, no): the mover would overlap it before its end, by more
/// than kWayInOverlapM (at its end they may touch, as places do).
constexpr double kWayInOverlapM = 0.001;
bool onWayIn(const Eigen::Vector2d& place, double radius_m, const std::vector<Eigen::Vector2d>& way,
             double mover_radius_m) {
  const double contact = radius_m + mover_radius_m - kWayInOverlapM;
  for (size_t i = 0; i + 1 < way.size(); ++i) {
    const Eigen::Vector2d d = way[i + 1] - way[i];
    const double t = d.squaredNorm() < 1e-12 ? 0.0 : std::clamp((place - way[i]).dot(d) / d.squaredNorm(), 0.0, 1.0);
    if (i + 2 == way.size() && t >= 1) continue;  // the end itself
    if ((place - (way[i] + t * d)).norm() < contact) return true;
  }
  return false;
}

/// Where a robot along `way` stops short of its end: the last point of it `stop_radius_m`
/// from the end (nothing when the way is unknown, or never that far from its end).
std::optional<Eigen::Vector2d> stopShortAt(const std::vector<Eigen::Vector2d>& way, double stop_radius_m) {
  if (way.empty()) return std::nullopt;
  const Eigen::Vector2d& end = way.back();
  for (size_t i = way.size() - 1; i-- > 0;) {
    if ((way[i] - end).norm() < stop_radius_m) continue;
    // Between way[i] (outside) and way[i + 1] (inside): where the way crosses the radius.
    const Eigen::Vector2d a = way[i] - end, d = way[i + 1] - way[i];
    const double qa = d.squaredNorm(), qb = 2 * a.dot(d), qc = a.squaredNorm() - stop_radius_m * stop_radius_m;
    const double t =
        qa < 1e-12 ? 0.0 : std::clamp((-qb - std::sqrt(std::max(0.0, qb * qb - 4 * qa * qc))) / (2 * qa), 0.0, 1.0);
    return Eigen::Vector2d(way[i] + t * d);
  }
  return std::nullopt;
}

/// Whether `b`, a robot of the step, is queued behind a robot ending at `end_point` (see
/// motionContacts): bound for the same target, its end not reaching it, farther from it.
bool queuedBehind(const BodyAtStart& b, const Eigen::Vector2d& end_point,
                  std::vector<BodyAtStart>::const_iterator target, const std::vector<BodyAtStart>& bodies,
                  double reach_m) {
  return target != bodies.end() && b.target == target->name &&
         !endsAgainst(b.final_position, b.radius_m, target->final_position, target->radius_m, reach_m) &&
         (b.final_position - target->final_position).norm() > (end_point - target->final_position).norm();
}

/// Whether a robot at `position` (`radius_m`) ending at `end` waits, onto a flat goal, for
/// one (`other_radius_m`) ending at `other_end` along `other_way`: its place lies on that
/// one's way in, not the other way round (`way`: its own), and it does not already stand
/// on that way (then waiting unseals nothing).
bool waitsOntoFlatGoal(const Eigen::Vector2d& position, double radius_m, const Eigen::Vector2d& end,
                       const std::vector<Eigen::Vector2d>& way, const Eigen::Vector2d& other_end, double other_radius_m,
                       const std::vector<Eigen::Vector2d>& other_way) {
  return onWayIn(end, radius_m, other_way, other_radius_m) && !onWayIn(position, radius_m, other_way, other_radius_m) &&
         !onWayIn(other_end, other_radius_m, way, radius_m);
}
}  // namespace

MotionContacts motionContacts(const Eigen::Vector2d& position, double radius_m, const Eigen::Vector2d& end_point,
                              int step, const std::string& action, const std::string& target,
                              const std::vector<BodyAtStart>& bodies, double reach_m, double arrival_radius_m,
                              const std::vector<Eigen::Vector2d>& way) {
  MotionContacts out;
  const BodyAtStart* load = nullptr;
  for (const BodyAtStart& b : bodies)
    if (b.object && b.step >= 0 && b.step == step && b.action == action && b.target == target &&
        (b.position - position).norm() <= task::togetherDistance(radius_m + b.radius_m, arrival_radius_m)) {
      load = &b;
      out.load = b.name;
      out.load_end = b.final_position;
      out.load_at = b.position;
      break;
    }
  const auto at_target =
      std::find_if(bodies.begin(), bodies.end(), [&](const BodyAtStart& b) { return b.name == target; });
  // Queued: its end point does not reach its target (a body), only robots ending nearer it.
  const bool queued = !load && at_target != bodies.end() &&
                      !endsAgainst(end_point, radius_m, at_target->final_position, at_target->radius_m, reach_m);
  // Onto a flat goal: queued behind a robot bound for it whose way in its place lies on,
  // and not the other way round, unless it stands on that way already (then waiting
  // unseals nothing).
  const bool to_flat_goal = !load && !target.empty() && at_target == bodies.end();
  // Where it would stand stopping short of its place (the stop radius), for a robot of its
  // meeting still on its way in.
  const std::optional<Eigen::Vector2d> short_at = stopShortAt(way, task::stopRadius(arrival_radius_m));
  bool stops_short = true;
  for (const BodyAtStart& b : bodies) {
    if (&b == load) continue;
    const bool same_meeting = b.step == step && !b.object && b.target == target && b.name != target;
    const bool ends_against = endsAgainst(end_point, radius_m, b.final_position, b.radius_m, reach_m);
    if (to_flat_goal && same_meeting) {
      if (waitsOntoFlatGoal(position, radius_m, end_point, way, b.final_position, b.radius_m, b.way))
        out.after.insert(b.name);
      if (waitsOntoFlatGoal(b.position, b.radius_m, b.final_position, b.way, end_point, radius_m, way))
        out.awaited_by.insert(b.name);
    }
    if (same_meeting && ends_against && queuedBehind(b, end_point, at_target, bodies, reach_m))
      out.awaited_by.insert(b.name);
    // Stopping short, it would stand against the place of a robot of its meeting that its
    // own place leaves clear: that one could not come to its place; it ends at its own,
    // stopping short for none.
    if (same_meeting && !ends_against && short_at && !load &&
        endsAgainst(*short_at, radius_m, b.final_position, b.radius_m, reach_m))
      out.awaited_by.insert(b.name), stops_short = false;
    if (ends_against) {
      out.ends_against.insert(b.name);
      if (b.step == step && !b.object && b.name != target && !out.awaited_by.count(b.name)) out.beside.insert(b.name);
      if (queued && same_meeting &&
          (b.final_position - at_target->final_position).norm() < (end_point - at_target->final_position).norm())
        out.after.insert(b.name);
    }
    if (load && endsAgainst(load->final_position, load->radius_m, b.final_position, b.radius_m, reach_m))
      out.load_ends_against.insert(b.name);
  }
  if (!stops_short) out.beside.clear();
  return out;
}

AllowedContacts::AllowedContacts(const std::vector<std::string>& names, const std::vector<double>& radii,
                                 const std::vector<DecidedMotion>& motions, double reach_m)
    : radii_(radii), reach_m_(reach_m) {
  const auto n = static_cast<int>(radii.size());
  if (names.size() != radii.size())
    throw Error("allowed contacts: " + std::to_string(names.size()) + " names and " + std::to_string(n) + " radii");
  const auto index = [&](const std::string& name) {
    const auto it = std::find(names.begin(), names.end(), name);
    return it == names.end() ? -1 : static_cast<int>(it - names.begin());
  };
  for (const DecidedMotion& m : motions) {
    if (m.entity < 0 || m.entity >= n || m.target >= n)
      throw Error("allowed contacts: a motion names an entity outside the " + std::to_string(n) + " given");
    if (m.target >= 0) exempt_.insert(ordered(m.entity, m.target));
    const int load = index(m.contacts.load);
    if (load >= 0) exempt_.insert(ordered(m.entity, load));
    for (const std::string& b : m.contacts.ends_against)
      if (const int k = index(b); k >= 0) ends_against_.push_back({m.entity, m.end, k});
    for (const std::string& b : m.contacts.load_ends_against)
      if (const int k = index(b); k >= 0 && load >= 0) ends_against_.push_back({load, m.contacts.load_end, k});
  }
}

AllowedContacts::AllowedContacts(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                                 const std::vector<Eigen::Vector2d>& starts, const std::vector<Eigen::Vector2d>& ends,
                                 const std::vector<bool>& moves, const std::vector<double>& radii, double reach_m) {
  const auto n = static_cast<int>(ends.size());
  if (moves.size() != ends.size() || radii.size() != ends.size() || starts.size() != ends.size() ||
      spec.entities.size() != ends.size())
    throw Error("allowed contacts: " + std::to_string(spec.entities.size()) + " entities, " +
                std::to_string(starts.size()) + " start positions, " + std::to_string(ends.size()) +
                " end positions, " + std::to_string(moves.size()) + " motion flags and " +
                std::to_string(radii.size()) + " radii");
  const std::vector<std::string> names = spec.entityNames();
  // Every body as the step's motions see it when the step begins.
  std::vector<BodyAtStart> bodies;
  for (int e = 0; e < n; ++e) {
    if (!(radii[e] > 0)) continue;
    BodyAtStart b;
    b.name = names[e], b.position = starts[e], b.final_position = ends[e], b.radius_m = radii[e];
    b.object = spec.entities[e].kind == task::EntityKind::Object;
    bodies.push_back(b);
  }
  const auto bodyOf = [&](int e) {
    return std::find_if(bodies.begin(), bodies.end(), [&](const BodyAtStart& b) { return b.name == names[e]; });
  };
  for (const task::Token& t : tokens) {
    if (!t.isMotion()) continue;
    if (t.entity < 0 || t.entity >= n || t.target >= n)
      throw Error("allowed contacts: a token names an entity outside the " + std::to_string(n) + " given");
    if (const auto b = bodyOf(t.entity); b != bodies.end() && moves[t.entity])
      b->step = 0, b->action = t.action, b->target = t.target >= 0 ? names[t.target] : "";
  }
  std::vector<DecidedMotion> motions;
  std::set<std::string> loads;  // a load of two carriers belongs to the first
  for (const task::Token& t : tokens) {
    if (!t.isMotion()) continue;
    DecidedMotion m{t.entity, t.target, ends[t.entity], {}};
    if (radii[t.entity] > 0) {
      std::vector<BodyAtStart> others;
      for (const BodyAtStart& b : bodies)
        if (b.name != names[t.entity]) others.push_back(b);
      m.contacts = motionContacts(starts[t.entity], radii[t.entity], ends[t.entity], 0, t.action,
                                  t.target >= 0 ? names[t.target] : "", others, reach_m, spec.arrival_radius);
      if (spec.entities[t.entity].kind != task::EntityKind::Robot || !loads.insert(m.contacts.load).second)
        m.contacts.load.clear(), m.contacts.load_ends_against.clear();
    }
    motions.push_back(std::move(m));
  }
  *this = AllowedContacts(names, radii, motions, reach_m);
}

bool AllowedContacts::allowed(int a, int b, const Eigen::Vector2d& pa, const Eigen::Vector2d& pb) const {
  if (exempt_.count(ordered(a, b))) return true;
  const auto n = static_cast<int>(radii_.size());
  if (a < 0 || a >= n || b < 0 || b >= n) return false;
  for (const EndsAgainst& e : ends_against_) {
    if (e.entity == a && e.other == b && endsAgainst(e.end, radii_[a], pb, radii_[b], reach_m_)) return true;
    if (e.entity == b && e.other == a && endsAgainst(e.end, radii_[b], pa, radii_[a], reach_m_)) return true;
  }
  return false;
}

StepContacts::StepContacts(task::TaskSpec spec, std::vector<double> radii, double reach_m)
    : spec_(std::move(spec)), radii_(std::move(radii)), reach_m_(reach_m) {}

void StepContacts::beginStep(int step) {
  if (step != step_) ends_.clear(), allowed_ = {}, step_ = step;  // no exemption of the last step stays
}

void StepContacts::note(int step, int entity, const task::Token& token, const Eigen::Vector2d& end,
                        const std::vector<Eigen::Vector2d>& at) {
  beginStep(step);
  const auto n = static_cast<int>(spec_.entities.size());
  const auto name = [&](int i) { return i >= 0 && i < n ? spec_.entities[i].name : "entity " + std::to_string(i); };
  if (token.entity != entity)
    throw Error("the segment of " + name(entity) + " carries a token of " + name(token.entity) +
                ": not counted for the allowed contacts");
  if (entity < 0 || entity >= static_cast<int>(at.size()))
    throw Error("the segment of " + name(entity) +
                " names no entity with a pose: not counted for the allowed contacts");
  // Kept only once the step's contacts are worked out with it: a bad segment leaves the
  // step's others as they were.
  auto step_ends = ends_;
  step_ends[entity] = {token, end};
  std::vector<task::Token> tokens;
  std::vector<Eigen::Vector2d> ends = at;
  std::vector<bool> moves(at.size(), false);
  for (const auto& [e, te] : step_ends) {
    tokens.push_back(te.first);
    ends[e] = te.second;
    moves[e] = true;
  }
  try {
    allowed_ = AllowedContacts(spec_, tokens, at, ends, moves, radii_, reach_m_);
  } catch (const Error&) {
    allowed_ = {};  // every contact counts
    throw;
  }
  ends_ = std::move(step_ends);
}

}  // namespace ddace::exec
