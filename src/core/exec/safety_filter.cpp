#include "ddace/exec/safety_filter.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "ddace/common/angle.h"
#include "ddace/common/error.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

void SafetyParams::validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    throw Error("safety filter parameter '" + field + "' " + why);
  };
  auto nonneg = [&](double v, const char* f) {
    if (!(v >= 0) || !std::isfinite(v)) bad(f, "must be a finite number >= 0");
  };
  auto pos = [&](double v, const char* f) {
    if (!(v > 0) || !std::isfinite(v)) bad(f, "must be a positive finite number");
  };
  nonneg(margin_m, "margin_m");
  pos(projection_m, "projection_m");
  pos(barrier_gain_hz, "barrier_gain_hz");
  pos(range_m, "range_m");
  pos(pose_max_age_s, "pose_max_age_s");
  if (!(blocked_fraction > 0 && blocked_fraction < 1)) bad("blocked_fraction", "must be in (0, 1)");
  pos(resolve_after_s, "resolve_after_s");
  pos(deadlock_after_s, "deadlock_after_s");
  if (deadlock_after_s <= resolve_after_s) bad("deadlock_after_s", "must exceed resolve_after_s");
  if (!(wait_limit_s >= deadlock_after_s) || !std::isfinite(wait_limit_s))
    bad("wait_limit_s", "must be finite and at least deadlock_after_s");
  pos(progress_m, "progress_m");
}

BodyShape bodyShape(const task::Entity& e) {
  const task::Footprint f = task::footprint(e);  // task.yaml's footprint or its kind's default
  return {f.radius_m, f.obstacle};
}

bool endsAgainst(const Eigen::Vector2d& end_point, double self_radius_m, const Eigen::Vector2d& position,
                 double radius_m, double reach_m) {
  return radius_m > 0 && position.allFinite() && (position - end_point).norm() < self_radius_m + radius_m + reach_m;
}

bool endedAtContact(const SafetyCommand& c, double distance_to_end_m, double stop_radius_m) {
  return !c.at_contact_with.empty() && distance_to_end_m <= stop_radius_m;
}

Eigen::Vector2d closestFeasible(const Eigen::Vector2d& z0, const std::vector<HalfPlane>& cs) {
  constexpr double kTol = 1e-10;
  auto feasible = [&](const Eigen::Vector2d& z) {
    for (const HalfPlane& c : cs)
      if (c.a.dot(z) > c.b + kTol * (1 + std::abs(c.b))) return false;
    return true;
  };
  if (feasible(z0)) return z0;
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector2d out = Eigen::Vector2d::Zero();
  // One active constraint: the projection of z0 on the line of one it violates. Feasible,
  // it is optimal (the nearest point of a half-plane containing the feasible set).
  for (const HalfPlane& c : cs) {
    const double n2 = c.a.squaredNorm();
    if (n2 <= 0 || c.a.dot(z0) <= c.b) continue;
    const Eigen::Vector2d z = z0 - ((c.a.dot(z0) - c.b) / n2) * c.a;
    const double cost = (z - z0).squaredNorm();
    if (cost < best && feasible(z)) best = cost, out = z;
  }
  if (std::isfinite(best)) return out;
  // Two active constraints: the vertex of their lines.
  for (size_t i = 0; i < cs.size(); ++i)
    for (size_t j = i + 1; j < cs.size(); ++j) {
      const double det = cs[i].a.x() * cs[j].a.y() - cs[i].a.y() * cs[j].a.x();
      if (std::abs(det) < 1e-14 * cs[i].a.norm() * cs[j].a.norm()) continue;
      const Eigen::Vector2d z((cs[i].b * cs[j].a.y() - cs[j].b * cs[i].a.y()) / det,
                              (cs[i].a.x() * cs[j].b - cs[j].a.x() * cs[i].b) / det);
      const double cost = (z - z0).squaredNorm();
      if (cost < best && feasible(z)) best = cost, out = z;
    }
  return out;
}

SafetyFilter::SafetyFilter(const SafetyParams& params, double wheel_base_m, double max_wheel_speed_mps,
                           double max_turn_rate_radps)
    : params_(params),
      wheel_base_m_(wheel_base_m),
      max_wheel_mps_(max_wheel_speed_mps),
      max_turn_radps_(max_turn_rate_radps) {
  params_.validate();
  if (!(wheel_base_m > 0) || !(max_wheel_speed_mps > 0) || !(max_turn_rate_radps > 0))
    throw Error("safety filter: wheel base, wheel speed and turn rate limits must be positive");
}

namespace {

/// The robot in one cycle: its centre `x`, heading `e`, and the controlled point `p`,
/// `l` ahead of the axle. A command z = (v, l w) moves p by z1 e + z2 e_perp.
struct Frame {
  Eigen::Vector2d x, e, e_perp, p;
  double l;
  /// A table-frame vector in the robot's frame (the frame of z).
  Eigen::Vector2d local(const Eigen::Vector2d& v) const { return {v.dot(e), v.dot(e_perp)}; }
};

}  // namespace

/// What a go-round decides its side from: the robot's frame and radius, the bodies, its load.
struct SafetyFilter::Scene {
  const Frame* frame;
  const std::vector<SafetyBody>* bodies;
  const SafetyBody* load;
  double self_radius_m;
  const std::string* target;
  /// The disc held: the load's (`of_load`, carrying) or the robot's own.
  Disc held(bool of_load) const {
    return of_load && load ? Disc{load->position, load->radius_m} : Disc{frame->x, self_radius_m};
  }
  /// Whether the held disc may end touching `b` (the target, or a body its end point touches).
  bool endsAt(const SafetyBody& b, bool of_load) const {
    return b.name == *target || (of_load && load ? b.load_touchable : b.touchable);
  }
};

namespace {

/// The body nearest to holding the robot or its load (not the target), to go round.
struct Nearest {
  double h = std::numeric_limits<double>::infinity();
  Eigen::Vector2d round_left{0, 0};  ///< unit z moving the held disc round it, keeping it on the left
  const SafetyBody* body = nullptr;
  bool of_load = false;  ///< held by the load's disc (else the robot's)
};

/// One cycle's half-planes in z, the body each belongs to (-1 for the limits), the body to
/// go round, and the smallest gap to any body.
struct Barriers {
  std::vector<HalfPlane> cs;
  std::vector<int> owner;
  Nearest nearest;
  double clearance_m = 1e9;
  void add(const HalfPlane& c, int body) { cs.push_back(c), owner.push_back(body); }
};

bool isLoad(const SafetyBody* load, const SafetyBody& b) {
  return load && b.name == load->name;
}
bool mayTouch(const SafetyBody& b, const std::string& target) {
  return b.name == target || b.touchable;
}

/// The command z moving the carried load's centre q (at r = q - x, q' = z1 e + (z2 / l)
/// r^perp) along `t` (robot frame); none (zero) when the load is beside or behind the robot:
/// no lever to steer it with.
Eigen::Vector2d loadLever(const Eigen::Vector2d& t, const Frame& f, const SafetyBody& load) {
  const Eigen::Vector2d r = f.local(load.position - f.x);
  if (!(r.x() > 1e-6)) return Eigen::Vector2d::Zero();
  return Eigen::Vector2d(t.x() + t.y() * r.y() / r.x(), f.l * t.y() / r.x());
}

/// Records `b` as the body nearest to holding the disc if its barrier value `h` is the
/// smallest so far; `a` is the unit vector from the body to the disc, robot frame. Going
/// round keeping the body on the left moves the disc along t = (-a.y, a.x): for the
/// robot's point z = t; for the load at r = q - x (q' = z1 e + (z2 / l) r^perp), the z
/// that moves q along t.
void considerNearest(Nearest& n, double h, const Eigen::Vector2d& a, const SafetyBody& b, const Frame& f,
                     const SafetyBody* load) {
  if (!(h < n.h)) return;
  const Eigen::Vector2d t(-a.y(), a.x());
  const Eigen::Vector2d z = load ? loadLever(t, f, *load) : t;
  if (z.norm() < 1e-9) return;  // the load beside or behind: no lever to go round with
  n = {h, z.normalized(), &b, load != nullptr};
}

/// The barrier of body `b` on the carried load's disc: q' = z1 e + (z2 / l) r^perp, r = q - x.
void loadBarrier(Barriers& out, const SafetyParams& sp, const Frame& f, const SafetyBody& load, const SafetyBody& b,
                 int index, const std::string& target, double share) {
  const double centres = (b.position - load.position).norm();
  if (centres <= 1e-9) return;
  const Eigen::Vector2d n = (load.position - b.position) / centres;
  const Eigen::Vector2d r = load.position - f.x, r_perp(-r.y(), r.x());
  const bool touch = b.name == target || b.load_touchable;
  const double h = centres - (load.radius_m + b.radius_m + (touch ? 0.0 : sp.margin_m));
  if (b.name != target) considerNearest(out.nearest, h, f.local(n), b, f, &load);
  out.clearance_m = std::min(out.clearance_m, centres - load.radius_m - b.radius_m);
  out.add({Eigen::Vector2d(-n.dot(f.e), -n.dot(r_perp) / f.l), std::max(0.0, share * sp.barrier_gain_hz * h)}, index);
}

/// The barrier of body `b` on the robot's own disc.
void robotBarrier(Barriers& out, const SafetyParams& sp, const Frame& f, double self_radius_m, const SafetyBody& b,
                  int index, const std::string& target, double share, bool disc_only) {
  const double centres = (b.position - f.x).norm();
  const double contact = self_radius_m + b.radius_m;
  out.clearance_m = std::min(out.clearance_m, centres - contact);
  HalfPlane c;
  if (disc_only && !mayTouch(b, target)) {
    // Its disc a margin off (x' = v e), not the point ahead: leaving a ring by a gap.
    if (centres < 1e-9) return;
    const Eigen::Vector2d m = (f.x - b.position) / centres;
    const double h = centres - contact - sp.margin_m;
    considerNearest(out.nearest, h, f.local(m), b, f, nullptr);
    out.add({Eigen::Vector2d(-m.dot(f.e), 0.0), std::max(0.0, share * sp.barrier_gain_hz * h)}, index);
    return;
  }
  if (mayTouch(b, target)) {
    // The motion's own target: the centres may close in to contact, no margin.
    if (centres < 1e-9) return;
    const Eigen::Vector2d n = (f.x - b.position) / centres;
    const double h = centres - contact;
    c.a = Eigen::Vector2d(-n.dot(f.e), 0.0);  // the centre moves with v alone
    c.b = std::max(0.0, share * sp.barrier_gain_hz * h);
    // A body it ends against but not its target, in the way short of the end (a robot
    // parked where this one ends touching it, approached from the wrong side): held, it
    // is gone round as any other body. Its target it ends at, not round.
    if (b.name != target) considerNearest(out.nearest, h, f.local(n), b, f, nullptr);
  } else {
    const Eigen::Vector2d d = f.p - b.position;
    const double dist = d.norm();
    if (dist < 1e-9) return;
    const Eigen::Vector2d n = d / dist;
    const double h = dist - (contact + sp.margin_m + f.l);
    c.a = -f.local(n);
    c.b = std::max(0.0, share * sp.barrier_gain_hz * h);
    considerNearest(out.nearest, h, -c.a, b, f, nullptr);  // -c.a: away from it, in the robot's frame
    // Nearer contact than the point's barrier reaches (a robot leaving a body it ended
    // against turns away from it): the disc itself never closes in within half the margin,
    // so it cannot graze it -- nor drift onto it on the tracking noise, as a barrier to
    // contact let it on a measured gap wider than the true one. (The whole margin held two
    // robots passing each other in a ring so tight that more of them deadlocked.)
    if (const double gap = centres - contact; gap < sp.margin_m + f.l && centres > 1e-9) {
      const Eigen::Vector2d m = (f.x - b.position) / centres;
      const double h = gap - sp.margin_m / 2;
      out.add({Eigen::Vector2d(-m.dot(f.e), 0.0), std::max(0.0, share * sp.barrier_gain_hz * h)}, index);
    }
  }
  out.add(c, index);
}

/// The wheel limits as half-planes in z: |v|, |w| and each wheel (v -+ w b/2 = z1 -+ k z2).
void addWheelLimits(Barriers& out, double l, double wheel_base_m, double max_wheel_mps, double max_turn_radps) {
  const double vmax = max_wheel_mps, zw = l * max_turn_radps, k = wheel_base_m / (2 * l);
  for (const HalfPlane& c :
       {HalfPlane{{1, 0}, vmax}, HalfPlane{{-1, 0}, vmax}, HalfPlane{{0, 1}, zw}, HalfPlane{{0, -1}, zw},
        HalfPlane{{1, -k}, vmax}, HalfPlane{{-1, k}, vmax}, HalfPlane{{1, k}, vmax}, HalfPlane{{-1, -k}, vmax}})
    out.add(c, -1);
}

const SafetyBody* findBody(const std::vector<SafetyBody>& bodies, const std::string& name) {
  const auto b = std::find_if(bodies.begin(), bodies.end(), [&](const SafetyBody& s) { return s.name == name; });
  return b == bodies.end() ? nullptr : &*b;
}

/// Held by bodies the motion may end against only, within the margin of touching one:
/// that one's name ("" otherwise).
std::string atContactWith(const std::vector<std::string>& blocking, const std::vector<SafetyBody>& bodies,
                          const std::string& target, const Eigen::Vector2d& x, double self_radius_m, double margin_m) {
  std::string touching;
  for (const std::string& name : blocking) {
    const SafetyBody* b = findBody(bodies, name);
    if (!b || !mayTouch(*b, target)) return "";
    if (touching.empty() && (b->position - x).norm() - self_radius_m - b->radius_m <= margin_m) touching = b->name;
  }
  return touching;
}

/// The report of a deadlock: the robot, how long it has not advanced, and the bodies that
/// held it since (`held_by`; none recorded: the bodies within a margin of holding it).
std::string deadlockReason(const std::string& self_name, double stuck_s, std::vector<std::string> held_by,
                           const std::vector<SafetyBody>& bodies, const Eigen::Vector2d& x, double self_radius_m,
                           const SafetyParams& sp) {
  if (held_by.empty())
    for (const SafetyBody& b : bodies)
      if (b.radius_m > 0 && (b.position - x).norm() - self_radius_m - b.radius_m < 3 * sp.margin_m + sp.projection_m)
        held_by.push_back(b.name);
  std::string names;
  for (const auto& n : held_by) names += (names.empty() ? "" : ", ") + n;
  char what[96];
  std::snprintf(what, sizeof what, " has not advanced %.0f cm along its path in %.1f s", sp.progress_m * 100, stuck_s);
  return "deadlock: " + self_name + what + ", held by the safety filter" +
         (names.empty() ? std::string() : " against " + names);
}

/// Which edge of a standing group spanning [right_rad, left_rad] the robot passes by (+1:
/// the right one): the one its command turns least to (0: that side does not block it).
double edgeSide(const Eigen::Vector2d& z0, double right_rad, double left_rad, const Frame& f) {
  // The way the robot wants to go: its command's point velocity, else its heading.
  const Eigen::Vector2d dir = z0.x() * f.e + z0.y() * f.e_perp;
  const Eigen::Vector2d way = dir.norm() > 1e-9 ? dir : f.e;
  const double want = std::atan2(way.y(), way.x());
  const double to_right = std::max(0.0, wrapAngle(want - right_rad));
  const double to_left = std::max(0.0, wrapAngle(left_rad - want));
  return to_left < to_right ? -1 : 1;
}

}  // namespace

SafetyCommand SafetyFilter::passThrough(const Pose2D& self, double self_radius_m, const WheelSpeeds& nominal,
                                        const std::vector<SafetyBody>& bodies, const SafetyBody* load) const {
  SafetyCommand out;
  for (const SafetyBody& b : bodies)
    if (b.radius_m > 0 && b.position.allFinite() && !isLoad(load, b))
      out.clearance_m = std::min(out.clearance_m, (b.position - self.position()).norm() - self_radius_m - b.radius_m);
  out.wheels = nominal;
  out.v_mps = (nominal.left_mps + nominal.right_mps) / 2;
  out.w_radps = (nominal.right_mps - nominal.left_mps) / wheel_base_m_;
  return out;
}

SafetyCommand SafetyFilter::stop(const WheelSpeeds& nominal, std::string why) {
  SafetyCommand out;
  out.modified = !nominal.isZero();
  out.stale = true;
  out.reason = std::move(why);
  reset();
  return out;
}

std::string SafetyFilter::staleName(const std::string& self_name, const Pose2D& self, double self_age_s,
                                    const std::vector<SafetyBody>& bodies, const SafetyBody* load) const {
  const Eigen::Vector2d x = self.position();
  if (!(self_age_s <= params_.pose_max_age_s) || !x.allFinite() || !std::isfinite(self.yaw)) return self_name;
  const bool carrying = load && load->radius_m > 0;
  auto stale = [&](const SafetyBody& b) { return b.stale || !(b.age_s <= params_.pose_max_age_s); };
  if (carrying && (stale(*load) || !load->position.allFinite())) return load->name;
  for (const SafetyBody& b : bodies) {
    if (b.radius_m <= 0 || !b.position.allFinite() || isLoad(load, b)) continue;
    const bool near_load = carrying && (b.position - load->position).norm() <= params_.range_m;
    if (((b.position - x).norm() <= params_.range_m || near_load) && stale(b)) return b.name;
  }
  return "";
}

Eigen::Vector2d SafetyFilter::goRound(const Eigen::Vector2d& z0, const SafetyBody* body, bool of_load,
                                      const Eigen::Vector2d& round_left, const Scene& scene, double now_s) {
  // While resolving, the point goes around the nearest body on the side decided when the
  // go-round began (resolve_side_: +1 keeps it on the left): round a moving body (or with
  // its load) along the tangent of that body, round standing bodies toward the edge of
  // their group as the robot sees it (tangent bug: clear of the group once there). At
  // least a quarter of the top speed: a nominal that only turns on the spot would not get
  // round anything.
  if (!(now_s < resolve_until_s_ && body)) return z0;
  if (!decidedFor(body)) decideSide(z0, body, of_load, round_left, scene);
  const double speed = std::max(z0.norm(), 0.25 * max_wheel_mps_);
  if (!resolve_standing_) return speed * resolve_side_ * round_left;
  std::vector<const SafetyBody*> group;
  for (const std::string& name : resolve_group_)
    if (const SafetyBody* b = findBody(*scene.bodies, name)) group.push_back(b);
  const Frame& f = *scene.frame;
  if (leaving_) {
    // Inside a ring of standing bodies: out through the gap it fits, along the gap's normal
    // and steered onto the line through its middle, until its disc is past the gap by the
    // filter's clearance; then round the ring by the edge its command turns least to.
    const double past = scene.self_radius_m + params_.margin_m + params_.projection_m;
    if ((f.x - leaving_->middle).dot(leaving_->out) < past) {
      const Eigen::Vector2d u = f.x - leaving_->middle;
      const Eigen::Vector2d off_line = u - u.dot(leaving_->out) * leaving_->out;
      return speed * f.local((leaving_->out - off_line / scene.self_radius_m).normalized());
    }
    leaving_.reset();
    const GroupEdges out = groupEdges(group, scene.held(false));
    resolve_side_ = edgeSide(z0, out.right_rad, out.left_rad, f);
  }
  const GroupEdges edges = groupEdges(group, scene.held(false));
  const double heading = resolve_side_ > 0 ? edges.right_rad : edges.left_rad;
  return speed * f.local(Eigen::Vector2d(std::cos(heading), std::sin(heading)));
}

std::optional<SafetyFilter::Gap> SafetyFilter::wayOut(const std::vector<const SafetyBody*>& group,
                                                      const Scene& scene) const {
  // Enclosed: the group's bodies lie all round the robot, none half a turn from the next.
  const Eigen::Vector2d x = scene.frame->x;
  std::vector<std::pair<double, const SafetyBody*>> round;
  for (const SafetyBody* b : group) {
    const Eigen::Vector2d v = b->position - x;
    round.emplace_back(std::atan2(v.y(), v.x()), b);
  }
  if (round.size() < 3) return std::nullopt;
  std::sort(round.begin(), round.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::optional<Gap> widest;
  double widest_m = 2 * (scene.self_radius_m + params_.margin_m);  // its disc, a margin either side
  for (size_t k = 0; k < round.size(); ++k) {
    const auto& [a0, b0] = round[k];
    const auto& [a1, b1] = round[(k + 1) % round.size()];
    if ((k + 1 < round.size() ? a1 - a0 : a1 + 2 * M_PI - a0) >= M_PI) return std::nullopt;  // open that side
    const Eigen::Vector2d d = b1->position - b0->position;
    const double width = d.norm() - b0->radius_m - b1->radius_m;
    if (width < widest_m) continue;
    widest_m = width;  // the widest: the tracking noise narrows every gap
    widest = Gap{b0->position + (b0->radius_m + width / 2) / d.norm() * d,
                 Eigen::Vector2d(d.y(), -d.x()).normalized()};  // counter-clockwise neighbours: away from the robot
  }
  return widest;
}

bool SafetyFilter::decidedFor(const SafetyBody* body) const {
  // Whichever disc it now holds, the robot's or its load's: a carrier turning past a group
  // brings its own disc near it too, and deciding afresh from that disc flipped the side.
  return body && std::find(resolve_group_.begin(), resolve_group_.end(), body->name) != resolve_group_.end();
}

void SafetyFilter::decideSide(const Eigen::Vector2d& z0, const SafetyBody* body, bool of_load,
                              const Eigen::Vector2d& round_left, const Scene& scene) {
  // Which way round. A body that moves too runs its own filter: both keep each other on
  // the left (the right-hand rule), so two robots face to face veer apart, never the
  // same way. A body standing still decides nothing: the robot goes round on the side its
  // own command turns to (toward its end point, the shorter way), the right-hand rule on
  // a tie -- the other way it would go the long way round and its command would turn it
  // back into the body before it got there. Standing bodies it cannot pass between
  // (standingGroup) and that its motion does not end at are passed as one, by the edge
  // its command turns least to: round one of them, it would be led into the too-narrow gap
  // next to it and held there. Decided for a body or its whole group: a body of the group
  // nearest later keeps the side (decided again, it would flip halfway round); another
  // body is decided for afresh.
  resolve_group_.clear();
  resolve_side_ = 1;
  resolve_standing_ = false;
  leaving_.reset();
  if (!body) return;
  // Round one body: a moving one, or one of a group the motion ends at (its target, a body
  // its end point touches): such a group it follows round body by body, each the shorter
  // way, to its place there. Carrying, the disc held -- the load's or its own -- decides
  // the group and its edges (a carrier and the load it delivered stand touching: a wall
  // the load cannot pass between, round either of which it would be led into the other).
  const Disc held = scene.held(of_load);
  std::vector<const SafetyBody*> group{body};
  if (body->standing) group = standingGroup(*body, scene, held);
  const bool ends_there =
      std::any_of(group.begin(), group.end(), [&](const SafetyBody* b) { return scene.endsAt(*b, of_load); });
  // A group all round it has no edge to pass by: body by body, as before.
  const GroupEdges edges = groupEdges(group, held);
  const bool surrounds = edges.left_rad - edges.right_rad >= 2 * M_PI;
  // Ringed in by standing bodies it does not end at (a met robot leaving the robots that
  // met it): it leaves through the widest gap it fits.
  if (!ends_there && body->standing && !scene.load) leaving_ = wayOut(group, scene);
  if (leaving_) {
    for (const SafetyBody* b : group) resolve_group_.push_back(b->name);
    resolve_standing_ = true;
    return;
  }
  if (group.size() == 1 || ends_there || surrounds || !body->standing) {
    resolve_group_.push_back(body->name);
    if (body->standing) resolve_side_ = z0.dot(round_left) < 0 ? -1 : 1;
    return;
  }
  // A group in its way it passes by the edge its command turns least to. A carrier follows
  // the group's outline there, round body by body on that side (keeping them on its left
  // passes the right edge): its load, turned by a lever, cannot head straight past an edge
  // it touches.
  for (const SafetyBody* b : group) resolve_group_.push_back(b->name);
  resolve_standing_ = !scene.load;
  resolve_side_ = edgeSide(z0, edges.right_rad, edges.left_rad, *scene.frame);
}

std::vector<const SafetyBody*> SafetyFilter::standingGroup(const SafetyBody& first, const Scene& scene,
                                                           const Disc& held) const {
  // Too narrow to pass: a gap below the held disc with the clearance the filter keeps
  // either side (the margin, reached by a point projection_m ahead of the axle).
  const double passable = 2 * (held.radius_m + params_.margin_m + params_.projection_m);
  std::vector<const SafetyBody*> group{&first};
  for (size_t k = 0; k < group.size(); ++k)
    for (const SafetyBody& b : *scene.bodies) {
      if (!b.standing || b.radius_m <= 0 || !b.position.allFinite() || isLoad(scene.load, b)) continue;
      if (std::find(group.begin(), group.end(), &b) != group.end()) continue;
      if ((b.position - group[k]->position).norm() - b.radius_m - group[k]->radius_m < passable) group.push_back(&b);
    }
  return group;
}

SafetyFilter::GroupEdges SafetyFilter::groupEdges(const std::vector<const SafetyBody*>& group, const Disc& held) const {
  // The directions (table frame) in which the held disc, a margin off, grazes each body,
  // measured from the direction of the first body (a group is contiguous as seen from
  // outside it): the group spans [right, left] counter-clockwise.
  const Eigen::Vector2d x = held.centre;
  if (group.empty()) return {};
  const Eigen::Vector2d r0 = group.front()->position - x;
  const double ref = std::atan2(r0.y(), r0.x());
  double lo = 0, hi = 0;
  for (const SafetyBody* b : group) {
    const Eigen::Vector2d v = b->position - x;
    const double d = v.norm(), reach = b->radius_m + held.radius_m + params_.margin_m;
    const double phi = wrapAngle(std::atan2(v.y(), v.x()) - ref);
    const double half = d > reach ? std::asin(reach / d) : M_PI / 2;
    lo = std::min(lo, phi - half), hi = std::max(hi, phi + half);
  }
  return {ref + lo, ref + hi};
}

SafetyCommand SafetyFilter::filter(const std::string& self_name, const Pose2D& self, double self_radius_m,
                                   double self_age_s, const WheelSpeeds& nominal, double progress_m,
                                   const std::vector<SafetyBody>& bodies, const std::string& target, double now_s,
                                   const SafetyBody* load) {
  // Disabled, the filter is a pass-through: the follower's own stale-pose rule (the
  // tracker's stale flag) governs, as without a filter; its pose-age bound is part of the
  // filter (a barrier built on old poses is no barrier).
  if (!params_.enabled) return passThrough(self, self_radius_m, nominal, bodies, load);
  const std::string stale = staleName(self_name, self, self_age_s, bodies, load);
  if (!stale.empty()) return stop(nominal, "pose of " + stale + " is stale");

  const double l = params_.projection_m;
  const Eigen::Vector2d x = self.position(), e(std::cos(self.yaw), std::sin(self.yaw));
  const Frame f{x, e, {-e.y(), e.x()}, x + l * e, l};
  if (!(load && load->radius_m > 0)) load = nullptr;  // carrying nothing

  // z = (v, l w): p' = z1 e + z2 e_perp, so |z - z0| is the change of p'.
  const double v0 = (nominal.left_mps + nominal.right_mps) / 2;
  const double w0 = (nominal.right_mps - nominal.left_mps) / wheel_base_m_;
  const Eigen::Vector2d z0(v0, l * w0);

  Barriers bs;
  bs.cs.reserve(bodies.size() + 8);
  for (size_t j = 0; j < bodies.size(); ++j) {
    const SafetyBody& b = bodies[j];
    if (b.radius_m <= 0 || !b.position.allFinite() || isLoad(load, b)) continue;
    // A robot on its way runs its own filter and takes the other half; a standing one does
    // not move away, so the whole constraint is this robot's.
    const double share = b.robot && !b.standing ? 0.5 : 1.0;
    const bool near_robot = (b.position - x).norm() <= params_.range_m;
    if (!near_robot && !(load && (b.position - load->position).norm() <= params_.range_m)) continue;
    if (load) loadBarrier(bs, params_, f, *load, b, static_cast<int>(j), target, share);
    const bool leaving_it =
        leaving_ && !load && std::find(resolve_group_.begin(), resolve_group_.end(), b.name) != resolve_group_.end();
    if (near_robot) robotBarrier(bs, params_, f, self_radius_m, b, static_cast<int>(j), target, share, leaving_it);
  }
  addWheelLimits(bs, l, wheel_base_m_, max_wheel_mps_, max_turn_radps_);

  const bool going_round = now_s < resolve_until_s_ && bs.nearest.body;
  const Nearest& nearest = bs.nearest;
  const Scene scene{&f, &bodies, load, self_radius_m, &target};
  const Eigen::Vector2d z =
      closestFeasible(goRound(z0, nearest.body, nearest.of_load, nearest.round_left, scene, now_s), bs.cs);
  SafetyCommand out;
  out.clearance_m = bs.clearance_m;
  out.v_mps = z.x();
  out.w_radps = z.y() / l;
  out.wheels = twistToWheels(out.v_mps, out.w_radps, wheel_base_m_);
  out.modified = (z - z0).norm() > 1e-9;

  // Blocked: the nominal moves the point, the filtered command hardly does.
  const double moving = 1e-3;  // m/s of the point: below this the nominal itself stands still
  out.blocked = z0.norm() > moving && z.norm() < params_.blocked_fraction * z0.norm();
  for (size_t i = 0; i < bs.cs.size(); ++i)
    if (bs.owner[i] >= 0 && bs.cs[i].a.dot(z) >= bs.cs[i].b - 1e-6 * (1e-3 + std::abs(bs.cs[i].b)) - 1e-9)
      out.blocking.push_back(bodies[bs.owner[i]].name);
  if (out.blocked && !out.blocking.empty())
    out.at_contact_with = atContactWith(out.blocking, bodies, target, x, self_radius_m, params_.margin_m);

  const bool decide = trackHold(out, self_name, x, self_radius_m, progress_m, bodies,
                                going_round ? nearest.body->name : std::string(), now_s);
  // Which way round, once per body while it is held: decided again every go-round, a
  // command pointing at a standing body (its path runs on behind it) turns it to one
  // side or the other with the noise, and the robot goes back and forth round it
  // without getting past.
  if (decide && !decidedFor(nearest.body)) decideSide(z0, nearest.body, nearest.of_load, nearest.round_left, scene);
  return out;
}

bool SafetyFilter::trackHold(SafetyCommand& out, const std::string& self_name, const Eigen::Vector2d& x,
                             double self_radius_m, double progress_m, const std::vector<SafetyBody>& bodies,
                             const std::string& going_round_of, double now_s) {
  // Held: the filter keeps changing the command and the robot does not advance progress_m
  // along its path. Held for resolve_after_s: go round (goRound) for resolve_after_s.
  if (!out.modified && !out.blocked) {
    stuck_since_s_ = -1;
    held_by_.clear();
    holders_.clear();
    resolve_group_.clear();  // free: the next hold decides its side afresh
    resolve_standing_ = false;
    leaving_.reset();
    return false;
  }
  if (stuck_since_s_ < 0 || progress_m >= stuck_progress_m_ + params_.progress_m) {
    stuck_since_s_ = waiting_since_s_ = now_s;
    stuck_progress_m_ = progress_m;
    waiting_at_ = x;
    held_by_.clear();
    holders_.clear();
  }
  // Passing a group of standing bodies by its edge, the robot leaves its path for a while
  // (round the ring it stands in, along a row): moving progress_m, it is not frozen; a crowd
  // it cannot get round is reported after wait_limit_s.
  if (resolve_standing_ && !going_round_of.empty() && (x - waiting_at_).norm() >= params_.progress_m)
    waiting_since_s_ = now_s, waiting_at_ = x;
  // A body holding it has moved progress_m since it began to: the robot waits its turn in
  // a crowd that clears (a queue, a crossing gone round one by one), it is not deadlocked.
  for (const auto& [name, at] : holders_) {
    const SafetyBody* b = findBody(bodies, name);
    if (b && (b->position - at).norm() >= params_.progress_m) {
      waiting_since_s_ = now_s;
      holders_.clear();
      break;
    }
  }
  // Who holds it since it last advanced: the bodies whose constraints shape the command,
  // and the one it goes round (a go-round command may touch no constraint at all).
  const auto held = [&](const std::string& name) {
    if (name.empty()) return;
    if (std::find(held_by_.begin(), held_by_.end(), name) == held_by_.end()) held_by_.push_back(name);
    const SafetyBody* b = findBody(bodies, name);
    const bool known = std::any_of(holders_.begin(), holders_.end(), [&](const auto& h) { return h.first == name; });
    if (b && !known) holders_.emplace_back(name, b->position);
  };
  for (const std::string& name : out.blocking) held(name);
  held(going_round_of);
  const double stuck_s = now_s - stuck_since_s_;
  const bool go_round = stuck_s >= params_.resolve_after_s && now_s >= resolve_until_s_;
  if (go_round) resolve_until_s_ = now_s + params_.resolve_after_s;
  // A deadlock: neither the robot nor any body holding it has moved for deadlock_after_s,
  // or the robot has not advanced for wait_limit_s while they move (a crowd that never
  // clears, robots circling each other).
  if (now_s - waiting_since_s_ < params_.deadlock_after_s && stuck_s < params_.wait_limit_s) return go_round;
  out.deadlock = true;
  out.reason = deadlockReason(self_name, stuck_s, held_by_, bodies, x, self_radius_m, params_);
  return go_round;
}

}  // namespace ddace::exec
