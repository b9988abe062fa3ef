#include "ddace/exec/safety_filter.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

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
  pos(progress_m, "progress_m");
}

BodyShape bodyShape(const task::Entity& e) {
  const task::Footprint f = task::footprint(e);  // task.yaml's footprint or its kind's default
  return {f.radius_m, f.obstacle};
}

bool endsAgainst(const Eigen::Vector2d& end_point, double self_radius_m, const Eigen::Vector2d& position,
                 double radius_m, double margin_m) {
  return radius_m > 0 && position.allFinite() && (position - end_point).norm() < self_radius_m + radius_m + margin_m;
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

SafetyCommand SafetyFilter::filter(const std::string& self_name, const Pose2D& self, double self_radius_m,
                                   double self_age_s, const WheelSpeeds& nominal, double progress_m,
                                   const std::vector<SafetyBody>& bodies, const std::string& target, double now_s,
                                   const SafetyBody* load) {
  SafetyCommand out;
  const double l = params_.projection_m;
  const Eigen::Vector2d x = self.position();
  const Eigen::Vector2d e(std::cos(self.yaw), std::sin(self.yaw)), e_perp(-e.y(), e.x());
  const Eigen::Vector2d p = x + l * e;

  auto stop = [&](std::string why) {
    out.wheels = {};
    out.v_mps = out.w_radps = 0;
    out.modified = !nominal.isZero();
    out.stale = true;
    out.reason = std::move(why);
    reset();
    return out;
  };
  // Disabled, the filter is a pass-through: the follower's own stale-pose rule (the
  // tracker's stale flag) governs, as without a filter; its pose-age bound is part of the
  // filter (a barrier built on old poses is no barrier).
  auto isLoad = [&](const SafetyBody& b) { return load && b.name == load->name; };
  if (!params_.enabled) {  // pass-through: only the clearance is measured
    for (const SafetyBody& b : bodies)
      if (b.radius_m > 0 && b.position.allFinite() && !isLoad(b))
        out.clearance_m = std::min(out.clearance_m, (b.position - x).norm() - self_radius_m - b.radius_m);
    out.wheels = nominal;
    out.v_mps = (nominal.left_mps + nominal.right_mps) / 2;
    out.w_radps = (nominal.right_mps - nominal.left_mps) / wheel_base_m_;
    return out;
  }
  if (!(self_age_s <= params_.pose_max_age_s) || !x.allFinite() || !std::isfinite(self.yaw))
    return stop("pose of " + self_name + " is stale");
  const bool carrying = load && load->radius_m > 0;
  if (carrying && (load->stale || !(load->age_s <= params_.pose_max_age_s) || !load->position.allFinite()))
    return stop("pose of " + load->name + " is stale");

  // z = (v, l w): p' = z1 e + z2 e_perp, so |z - z0| is the change of p'.
  const double v0 = (nominal.left_mps + nominal.right_mps) / 2;
  const double w0 = (nominal.right_mps - nominal.left_mps) / wheel_base_m_;
  const Eigen::Vector2d z0(v0, l * w0);

  std::vector<HalfPlane> cs;
  std::vector<int> owner;  // body index of each constraint, -1 for the limits
  // The body nearest to holding the robot or its load (not the target): the command z that
  // moves the held disc round it keeping it on the left, and whether it stands still.
  double nearest_h = std::numeric_limits<double>::infinity();
  Eigen::Vector2d round_left(0, 0);
  bool nearest_standing = false;
  const SafetyBody* nearest_body = nullptr;  // the go-round's side is decided per body (and disc: robot or load)
  bool nearest_of_load = false;
  // Going round keeping the body on the left is moving the disc along the tangent t =
  // (-a.y, a.x), a the unit vector from the body to the disc in the robot's frame. For the
  // robot's point, z = t; for the load at r = q - x (q' = z1 e + (z2 / l) r^perp), the z
  // that moves q along t.
  const auto nearest = [&](double h, const Eigen::Vector2d& a, const SafetyBody& b, bool of_load) {
    if (!(h < nearest_h)) return;
    const Eigen::Vector2d t(-a.y(), a.x());
    Eigen::Vector2d z = t;
    if (of_load) {
      const Eigen::Vector2d r = load->position - x;
      const double rx = r.dot(e), ry = r.dot(e_perp);  // the load ahead: rx > 0
      if (!(rx > 1e-6)) return;                        // beside or behind: no lever to go round with
      z = Eigen::Vector2d(t.x() + t.y() * ry / rx, l * t.y() / rx);
    }
    nearest_h = h, round_left = z.normalized(), nearest_standing = b.standing;
    nearest_body = &b, nearest_of_load = of_load;
  };
  cs.reserve(bodies.size() + 6);
  for (size_t j = 0; j < bodies.size(); ++j) {
    const SafetyBody& b = bodies[j];
    if (b.radius_m <= 0 || !b.position.allFinite() || isLoad(b)) continue;
    const double centres = (b.position - x).norm();
    const double load_centres = carrying ? (b.position - load->position).norm() : 1e9;
    if (centres > params_.range_m && load_centres > params_.range_m) continue;
    if (b.stale || !(b.age_s <= params_.pose_max_age_s)) return stop("pose of " + b.name + " is stale");
    const double share = b.robot ? 0.5 : 1.0;
    if (carrying && load_centres > 1e-9) {
      // The load's disc: q' = v e + w r^perp with r = q - x, i.e. z1 e + (z2 / l) r^perp.
      const Eigen::Vector2d n = (load->position - b.position) / load_centres;
      const Eigen::Vector2d r = load->position - x, r_perp(-r.y(), r.x());
      const bool touch = b.name == target || b.load_touchable;
      const double h = load_centres - (load->radius_m + b.radius_m + (touch ? 0.0 : params_.margin_m));
      if (b.name != target) nearest(h, Eigen::Vector2d(n.dot(e), n.dot(e_perp)), b, true);
      out.clearance_m = std::min(out.clearance_m, load_centres - load->radius_m - b.radius_m);
      cs.push_back(
          {Eigen::Vector2d(-n.dot(e), -n.dot(r_perp) / l), std::max(0.0, share * params_.barrier_gain_hz * h)});
      owner.push_back(static_cast<int>(j));
    }
    if (centres > params_.range_m) continue;
    const double contact = self_radius_m + b.radius_m;
    out.clearance_m = std::min(out.clearance_m, centres - contact);
    HalfPlane c;
    if (b.name == target || b.touchable) {
      // The motion's own target: the centres may close in to contact, no margin.
      if (centres < 1e-9) continue;
      const Eigen::Vector2d n = (x - b.position) / centres;
      const double h = centres - contact;
      c.a = Eigen::Vector2d(-n.dot(e), 0.0);  // the centre moves with v alone
      c.b = std::max(0.0, share * params_.barrier_gain_hz * h);
      // A body it ends against but not its target, in the way short of the end (a robot
      // parked where this one ends touching it, approached from the wrong side): held, it
      // is gone round as any other body. Its target it ends at, not round.
      if (b.name != target) nearest(h, Eigen::Vector2d(n.dot(e), n.dot(e_perp)), b, false);
    } else {
      const Eigen::Vector2d d = p - b.position;
      const double dist = d.norm();
      if (dist < 1e-9) continue;
      const Eigen::Vector2d n = d / dist;
      const double h = dist - (contact + params_.margin_m + l);
      c.a = Eigen::Vector2d(-n.dot(e), -n.dot(e_perp));
      c.b = std::max(0.0, share * params_.barrier_gain_hz * h);
      nearest(h, -c.a, b, false);  // -c.a: away from it, in the robot's frame
    }
    cs.push_back(c);
    owner.push_back(static_cast<int>(j));
  }
  // Limits: |v| and |w| and each wheel, as half-planes in z.
  const double vmax = max_wheel_mps_, zw = l * max_turn_radps_;
  const double k = wheel_base_m_ / (2 * l);  // wheel = v -+ w b/2 = z1 -+ k z2
  for (const HalfPlane& c :
       {HalfPlane{{1, 0}, vmax}, HalfPlane{{-1, 0}, vmax}, HalfPlane{{0, 1}, zw}, HalfPlane{{0, -1}, zw},
        HalfPlane{{1, -k}, max_wheel_mps_}, HalfPlane{{-1, k}, max_wheel_mps_}, HalfPlane{{1, k}, max_wheel_mps_},
        HalfPlane{{-1, -k}, max_wheel_mps_}}) {
    cs.push_back(c);
    owner.push_back(-1);
  }

  // Deadlock resolution: while resolving, the point goes around the nearest body on the
  // side decided when the go-round began (resolve_side_: +1 keeps it on the left). At least
  // a quarter of the top speed: a nominal that only turns on the spot would not get round
  // anything.
  // Which way round. A body that moves too runs its own filter: both keep each other on
  // the left (the right-hand rule), so two robots face to face veer apart, never the
  // same way. A body standing still decides nothing: the robot goes round on the side its
  // own command turns to (toward its end point, the shorter way), the right-hand rule on
  // a tie -- the other way it would go the long way round and its command would turn it
  // back into the body before it got there. Decided for one body: another body nearest
  // later in the go-round is decided for again (its own standing flag and side).
  const auto decideSide = [&] {
    resolve_side_ = nearest_standing && z0.dot(round_left) < 0 ? -1 : 1;
    if (nearest_body) resolve_body_ = nearest_body->name, resolve_of_load_ = nearest_of_load;
  };
  Eigen::Vector2d goal_z = z0;
  const bool going_round = now_s < resolve_until_s_ && nearest_body;
  if (going_round) {
    if (nearest_body->name != resolve_body_ || nearest_of_load != resolve_of_load_) decideSide();
    goal_z = std::max(z0.norm(), 0.25 * vmax) * resolve_side_ * round_left;
  }
  const Eigen::Vector2d z = closestFeasible(goal_z, cs);
  out.v_mps = z.x();
  out.w_radps = z.y() / l;
  out.wheels = twistToWheels(out.v_mps, out.w_radps, wheel_base_m_);
  out.modified = (z - z0).norm() > 1e-9;

  // Blocked: the nominal moves the point, the filtered command hardly does.
  const double moving = 1e-3;  // m/s of the point: below this the nominal itself stands still
  out.blocked = z0.norm() > moving && z.norm() < params_.blocked_fraction * z0.norm();
  for (size_t i = 0; i < cs.size(); ++i)
    if (owner[i] >= 0 && cs[i].a.dot(z) >= cs[i].b - 1e-6 * (1e-3 + std::abs(cs[i].b)) - 1e-9)
      out.blocking.push_back(bodies[owner[i]].name);
  if (out.blocked && !out.blocking.empty()) {
    std::string touching;
    bool only_ends = true;
    for (const std::string& name : out.blocking) {
      const auto b = std::find_if(bodies.begin(), bodies.end(), [&](const SafetyBody& s) { return s.name == name; });
      if (b == bodies.end() || !(b->name == target || b->touchable)) {
        only_ends = false;
        break;
      }
      if (touching.empty() && (b->position - x).norm() - self_radius_m - b->radius_m <= params_.margin_m)
        touching = b->name;
    }
    if (only_ends) out.at_contact_with = touching;
  }

  // Held: the filter keeps changing the command and the robot does not advance progress_m
  // along its path -- frozen in place, or circling with others (a livelock) alike. Held
  // for resolve_after_s: go round (above) for resolve_after_s; for deadlock_after_s: a
  // deadlock, reported.
  if (!out.modified && !out.blocked) {
    stuck_since_s_ = -1;
    held_by_.clear();
    resolve_body_.clear();  // free: the next hold decides its side afresh
    return out;
  }
  if (stuck_since_s_ < 0 || progress_m >= stuck_progress_m_ + params_.progress_m) {
    stuck_since_s_ = now_s;
    stuck_progress_m_ = progress_m;
    held_by_.clear();
  }
  // Who holds it since it last advanced: the bodies whose constraints shape the command,
  // and the one it goes round (a go-round command may touch no constraint at all).
  const auto held = [&](const std::string& name) {
    if (!name.empty() && std::find(held_by_.begin(), held_by_.end(), name) == held_by_.end()) held_by_.push_back(name);
  };
  for (const std::string& name : out.blocking) held(name);
  if (going_round) held(resolve_body_);
  const double stuck_s = now_s - stuck_since_s_;
  if (stuck_s >= params_.resolve_after_s && now_s >= resolve_until_s_) {
    resolve_until_s_ = now_s + params_.resolve_after_s;
    // Which way round (above), once per body while it is held: decided again every
    // go-round, a command pointing at a standing body (its path runs on behind it) turns
    // it to one side or the other with the noise, and the robot goes back and forth round
    // it without getting past.
    if (!nearest_body || nearest_body->name != resolve_body_ || nearest_of_load != resolve_of_load_) decideSide();
  }
  if (stuck_s >= params_.deadlock_after_s) {
    out.deadlock = true;
    std::vector<std::string> near = held_by_;
    if (near.empty())  // none recorded: the bodies within a margin of holding it
      for (const SafetyBody& b : bodies)
        if (b.radius_m > 0 && (b.position - x).norm() - self_radius_m - b.radius_m < 3 * params_.margin_m + l)
          near.push_back(b.name);
    std::string names;
    for (const auto& n : near) names += (names.empty() ? "" : ", ") + n;
    char what[96];
    std::snprintf(what, sizeof what, " has not advanced %.0f cm along its path in %.1f s", params_.progress_m * 100,
                  stuck_s);
    out.reason = "deadlock: " + self_name + what + ", held by the safety filter" +
                 (names.empty() ? std::string() : " against " + names);
  }
  return out;
}

}  // namespace ddace::exec
