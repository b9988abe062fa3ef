#include "ddace/exec/robot_controller.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "ddace/common/angle.h"
#include "ddace/common/error.h"
#include "ddace/exec/push_path.h"

namespace ddace::exec {

namespace {

/// The bodies standing round a carrier of radius `radius_m` pushing `load` (every other
/// standing body at its reach, exec::pushObstacle, as the push's plan takes them): where its
/// push may start (pushMayStartHere) and what its push planned again goes round.
std::vector<PushObstacle> standingRound(const std::vector<SafetyBody>& others, const SafetyBody& load,
                                        double radius_m) {
  std::vector<PushObstacle> out;
  for (const SafetyBody& b : others)
    if (b.standing && &b != &load)
      out.push_back(pushObstacle(b.position, radius_m + b.radius_m, load.radius_m + b.radius_m));
  return out;
}

}  // namespace

void ControllerParams::validate() const {
  gains.validate();
  safety.validate();
  if (!(stale_fail_s > 0) || !std::isfinite(stale_fail_s))
    throw Error("controller parameter 'stale_fail_s' must be a positive number of seconds");
}

RobotController::RobotController(std::string name, const ControllerParams& params)
    : name_(std::move(name)),
      params_(params),
      follower_(params.gains),
      filter_(params.safety, params.gains.wheel_base_m, params.gains.max_wheel_speed_mps,
              params.gains.max_turn_rate_radps) {
  params_.validate();
}

void RobotController::start(const PlannedPath& path, const std::string& target, double stop_radius_m,
                            double held_stop_radius_m, double place_stop_radius_m) {
  if (place_stop_radius_m <= 0) place_stop_radius_m = stop_radius_m;
  for (const double r : {stop_radius_m, held_stop_radius_m, place_stop_radius_m})
    if (!(r > 0) || !std::isfinite(r))
      throw Error("the stop radii of " + name_ + "'s motion must be positive numbers of metres");
  FollowerGains g = params_.gains;
  g.stop_radius_m = stop_radius_m;
  PathFollower f(g);
  f.setPath(path);  // throws for an empty or non-finite path, the last motion kept
  follower_ = std::move(f);
  stop_radius_m_ = stop_radius_m;
  held_stop_radius_m_ = held_stop_radius_m;
  place_stop_radius_m_ = std::min(stop_radius_m, place_stop_radius_m);
  target_ = target;
  contacts_ = {};
  push_planned_for_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  load_route_.clear();
  was_pushing_ = backing_off_ = false;
  filter_.reset();
  stale_since_s_ = -1;
}

void RobotController::setContacts(MotionContacts contacts) {
  contacts_ = std::move(contacts);
  push_planned_for_ = contacts_.load_at;
  load_route_.clear();
  was_pushing_ = false;
}

void RobotController::planLoadRoute(const SafetyBody& load) {
  if (!load_route_.empty()) return;
  // Unknown where it was planned for: the path as given was planned for the load there.
  if (!push_planned_for_.allFinite()) push_planned_for_ = load.position;
  load_route_ = loadRoute(follower_.points(), push_planned_for_, load.position, contacts_.load_end);
}

void RobotController::replanPush(const Pose2D& pose, const SafetyBody& load, double radius_m,
                                 const std::vector<PushObstacle>& standing) {
  if (!was_pushing_ && (load.position - push_planned_for_).norm() <= kPushReplanM) return;
  const int points = std::max(2, static_cast<int>(std::ceil(follower_.lengthM() / kPushPathSpacingM)));
  load_route_ = withRunUp(pose.position(), routeOnFrom(load_route_, load.position), radius_m + load.radius_m, standing);
  follower_.setPath(PlannedPath{pushPathAlong(pose.position(), load_route_, radius_m + load.radius_m, points, standing,
                                              /*push_from_behind=*/false),
                                {}});
  push_planned_for_ = load.position;
}

void RobotController::cancel() {
  backing_off_ = false;
  follower_.clear();
  target_.clear();
  contacts_ = {};
  filter_.reset();
  stale_since_s_ = -1;
}

ControlOutput RobotController::end(ControlOutput out, MotionState state, std::string message) {
  out.wheels = {};
  out.state = state;
  out.message = std::move(message);
  out.held = out.waiting_stale = false;
  cancel();
  return out;
}

ControlOutput RobotController::stale(ControlOutput out, const std::string& why, double now_s) {
  if (stale_since_s_ < 0) stale_since_s_ = now_s;
  out.wheels = {};
  const double for_s = now_s - stale_since_s_;
  if (for_s > params_.stale_fail_s) {
    char t[64];
    std::snprintf(t, sizeof t, " for %.2f s (longer than stale_fail_s)", for_s);
    return end(out, MotionState::Failed, why + t);
  }
  out.waiting_stale = true;
  out.message = why;
  return out;
}

ControlOutput RobotController::done(ControlOutput out, std::string message, const Pose2D& pose, double pose_age_s,
                                    double radius_m, std::vector<SafetyBody>& others, double now_s) {
  if (contacts_.load.empty() || contacts_.load_rides) return end(out, MotionState::Done, std::move(message));
  backing_off_ = true;
  done_message_ = std::move(message);
  return backOff(out, pose, pose_age_s, radius_m, others, now_s);
}

ControlOutput RobotController::backOff(ControlOutput out, const Pose2D& pose, double pose_age_s, double radius_m,
                                       std::vector<SafetyBody>& others, double now_s) {
  out.progress = 1.0;
  const SafetyBody* load = nullptr;
  for (SafetyBody& b : others) {
    if (b.name == contacts_.load) load = &b;
    b.touchable = b.name == contacts_.load;  // leaving it
    b.load_touchable = false;
  }
  const Eigen::Vector2d away = load ? Eigen::Vector2d(pose.position() - load->position) : Eigen::Vector2d::Zero();
  if (!load || away.norm() >= radius_m + load->radius_m + kPushBackOffM || away.norm() < 1e-9)
    return end(out, MotionState::Done, done_message_);
  // Forward or backward, whichever heads nearer straight away from the load, turning onto it.
  const double bearing = std::atan2(away.y(), away.x());
  const double ahead = wrapAngle(bearing - pose.yaw), behind = wrapAngle(bearing - pose.yaw - M_PI);
  const bool forward = std::abs(ahead) <= std::abs(behind);
  const double alpha = forward ? ahead : behind;
  const FollowerGains& g = params_.gains;
  const double turn = std::clamp(g.heading_gain * alpha, -g.max_turn_rate_radps, g.max_turn_rate_radps);
  const double v = std::abs(alpha) <= g.rotate_in_place_rad ? (forward ? 1 : -1) * g.min_speed_mps : 0.0;
  const double backed_m = away.norm() - radius_m - load->radius_m;
  const SafetyCommand c = filter_.filter(name_, pose, radius_m, pose_age_s, twistToWheels(v, turn, g.wheel_base_m),
                                         follower_.lengthM() + std::max(0.0, backed_m), others, target_, now_s);
  if (c.stale) return stale(out, c.reason, now_s);
  stale_since_s_ = -1;
  if (c.blocked || c.deadlock) return end(out, MotionState::Done, done_message_);  // no room: it stays
  out.wheels = c.wheels;
  return out;
}

ControlOutput RobotController::waitFor(ControlOutput out, const std::string& whom) {
  stale_since_s_ = -1;
  filter_.reset();  // waiting is no hold: its deadlock clock starts when it drives
  out.waiting_for = whom;
  out.message =
      name_ + " waits for " + whom + " to stand: its place lies behind " + whom + "'s, or on " + whom + "'s way in";
  return out;
}

ControlOutput RobotController::cycle(const Pose2D& pose, bool pose_stale, double pose_age_s, double radius_m,
                                     std::vector<SafetyBody>& others, double now_s) {
  ControlOutput out;
  if (!running()) return out;
  out.state = MotionState::Running;
  out.progress = follower_.progress();
  if (pose_stale || !pose.position().allFinite() || !std::isfinite(pose.yaw))
    return stale(out, "pose of " + name_ + " is stale", now_s);

  if (backing_off_) return backOff(out, pose, pose_age_s, radius_m, others, now_s);
  for (const SafetyBody& b : others)
    if (contacts_.after.count(b.name) && !b.standing) return waitFor(out, b.name);
  const SafetyBody* load = nullptr;
  for (const SafetyBody& b : others)
    if (!contacts_.load.empty() && b.name == contacts_.load) load = &b;
  // Behind its load, a carrier steers the load along the load's route -- its own path
  // beyond the load, on to the load's end point (exec/push_path.h) -- and the load's
  // arrival, not its own, ends the push. Not behind it, it goes round it to behind it along
  // its path; when the push broke (the load slid off its front) or the load moved off where
  // the path was planned for (something pushed it), round it again from where things are,
  // on along the rest of the same route.
  const bool pushes = load && !contacts_.load_rides;
  if (pushes) planLoadRoute(*load);
  const std::vector<PushObstacle> standing =
      pushes ? standingRound(others, *load, radius_m) : std::vector<PushObstacle>{};
  const auto push = pushes ? pushWheels(pose, load->position, load_route_, radius_m + load->radius_m, params_.gains,
                                        was_pushing_, standing)
                           : std::nullopt;
  if (pushes && !push) replanPush(pose, *load, radius_m, standing);
  was_pushing_ = push.has_value();
  // Ending beside a body other than its target that is still on its way (robots meeting
  // at one body, a line), it stops within the held stop radius: driven on to its exact
  // place it would close the way in of that one, whose place lies beside it. The last of
  // them to come ends where its own stop radius says.
  // Awaited by a robot queued behind it, it ends at its own place: stopping short on its
  // way in it would stand in the waiting one's.
  bool beside_moving = false;
  for (const SafetyBody& b : others) beside_moving = beside_moving || (!b.standing && contacts_.beside.count(b.name));
  const double own = contacts_.awaited_by.empty() || !contacts_.load.empty() ? stop_radius_m_ : place_stop_radius_m_;
  follower_.setStopRadius(beside_moving ? std::max(own, held_stop_radius_m_) : own);
  FollowerOutput o = follower_.compute(pose);
  out.progress = o.progress;
  out.distance_to_goal_m = o.distance_to_goal_m;
  if (push ? push->load_arrived : o.done) {
    stale_since_s_ = -1;
    return done(out, "", pose, pose_age_s, radius_m, others, now_s);
  }
  if (push) o.wheels = push->wheels;

  // What the motion may touch, as decided for its step: a body it ends against while that
  // body is at the end point, its load's likewise.
  const Eigen::Vector2d end_point = follower_.endPoint();
  const double reach = params_.safety.endsAgainstReachM();
  // A riding load is part of its carrier's body. A pushed one is while the carrier pushes
  // it (kept clear of others); otherwise it is a body like any other, except that the
  // carrier may touch it from behind (behindLoad), on its way to push it.
  const bool in_hand = load && (contacts_.load_rides || push);
  const bool from_behind = pushes && !push && behindLoad(pose.position(), load->position, load_route_);
  for (SafetyBody& b : others) {
    b.touchable = (from_behind && &b == load) || (contacts_.ends_against.count(b.name) &&
                                                  endsAgainst(end_point, radius_m, b.position, b.radius_m, reach));
    b.load_touchable = in_hand && contacts_.load_ends_against.count(b.name) &&
                       endsAgainst(contacts_.load_end, load->radius_m, b.position, b.radius_m, reach);
  }
  if (!in_hand) load = nullptr;
  const SafetyCommand c = filter_.filter(name_, pose, radius_m, pose_age_s, o.wheels, o.progress * follower_.lengthM(),
                                         others, target_, now_s, load);
  if (c.stale) return stale(out, c.reason, now_s);  // a body nearby is stale: as the robot's own pose
  stale_since_s_ = -1;
  if (c.deadlock && o.distance_to_goal_m <= held_stop_radius_m_) {
    // Held still near enough its end point that its true position is within the arrival
    // radius (bodies beside it, settled): it has arrived there, as when blocked below.
    out.progress = 1.0;
    return done(out, "held short of its end point: " + c.reason, pose, pose_age_s, radius_m, others, now_s);
  }
  if (c.deadlock) {
    char where[64];
    std::snprintf(where, sizeof where, ", %.1f cm from its end point", 100 * o.distance_to_goal_m);
    return end(out, MotionState::Failed, c.reason + where);
  }
  if (endedAtContact(c, o.distance_to_goal_m, held_stop_radius_m_)) {
    // A motion toward a body ends at contact with it: held there by a body it ends
    // against, within the held stop radius of its end point, it has arrived.
    out.ended_at_contact_with = c.at_contact_with;
    out.progress = 1.0;
    return done(out, "ended at contact with " + c.at_contact_with, pose, pose_age_s, radius_m, others, now_s);
  }
  if (c.blocked && o.distance_to_goal_m <= held_stop_radius_m_) {
    // Held short of its end point by bodies beside it (kept at the filter's margin), near
    // enough that its true position is within the arrival radius: it has arrived there.
    out.progress = 1.0;
    std::string by;
    for (const std::string& b : c.blocking) by += (by.empty() ? "" : ", ") + b;
    return done(out, "held short of its end point by " + by, pose, pose_age_s, radius_m, others, now_s);
  }
  out.wheels = c.wheels;
  out.held = c.blocked;
  if (c.blocked) out.blocking = c.blocking;
  return out;
}

}  // namespace ddace::exec
