// One robot's control cycle: the code that drives a robot, on the real table
// (path_follower_node) and in every simulator with bodies (exec::BodiesExecution) alike.
//
// Each cycle, from the robot's measured pose and the other bodies as tracked:
//   1. its own pose stale (the tracker says so, or too old): zero wheels at once; stale for
//      stale_fail_s, the motion fails naming the robot;
//   2. queued behind a robot of its step still on its way (MotionContacts::after): zero
//      wheels until that one stands (no deadlock clock runs meanwhile), so the places of
//      robots meeting at one body are taken from the inside out;
//   3. the path-following law (exec::PathFollower) gives the nominal wheels; within the
//      stop radius of the end point, the motion is done;
//   4. the safety filter (exec::SafetyFilter) changes them as little as keeps every body
//      clear, except what the motion may touch; a stale body near the robot counts as 1, a
//      deadlock the filter reports fails the motion naming the bodies that hold it;
//   5. held at contact with a body its motion ends against (exec::endedAtContact), or short
//      of its end point by bodies beside it, within the held stop radius of the end point,
//      the motion is done there;
//   6. the filtered wheels go out.
//
// What a motion may touch -- its target, the bodies its end point touches, its load and
// the bodies its load's end point touches (MotionContacts) -- is decided once per step
// from the step's end points (exec/motion_contacts.h) by the caller and given here; the
// controller never decides it from where bodies are while they move. A body it may touch
// as its ending is touchable only while that body is at the end point (endsAgainst from
// its measured position): two robots bound for one goal keep apart on the way. A load it
// pushes is touchable only from behind it (exec::behindLoad), part of its body only while
// it pushes it: a carrier never shoves its load off its line from the side.
//
// Owns: the order of the cycle, the stale clock, when a motion ends. Must not: know ROS,
// read a clock (time comes in), or decide where a motion ends or what it may touch.
// Units: metres, radians, seconds; table frame.
#pragma once

#include <memory>
#include <set>
#include <string>
#include <vector>

#include "ddace/exec/motion_contacts.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/push_path.h"
#include "ddace/exec/safety_filter.h"

namespace ddace::exec {

/// A robot's controller: its path-following law, its safety filter, and how long a stale
/// pose may last before the motion fails. config/execution.yaml, section path_follower.
struct ControllerParams {
  FollowerGains gains;        ///< path_follower/gains
  SafetyParams safety;        ///< path_follower/safety
  double stale_fail_s = 2.0;  ///< a pose stale this long during a motion fails it
  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
};

enum class MotionState : char { Idle, Running, Done, Failed };

/// What one control cycle decided.
struct ControlOutput {
  WheelSpeeds wheels;  ///< to the wheels now (zero unless Running and free to move)
  /// Running, or Done / Failed in the cycle the motion ends (the controller is Idle after).
  MotionState state = MotionState::Idle;
  double progress = 0;            ///< arc-length fraction of the path covered
  double distance_to_goal_m = 0;  ///< measured distance to the end point
  /// Failed: why, naming the robot and the cause; Done at contact: "ended at contact with
  /// X"; Running with wheels zero for a stale pose: whose (`waiting_stale`).
  std::string message;
  bool waiting_stale = false;         ///< wheels zero for a stale pose, not failed yet
  bool held = false;                  ///< the filter holds the robot (blocked)
  std::vector<std::string> blocking;  ///< the bodies holding it, when held
  std::string ended_at_contact_with;  ///< Done at contact: the body
  /// Running, not yet driving: the mover of its step it waits for (MotionContacts::after).
  std::string waiting_for;
};

class RobotController {
 public:
  /// Throws ddace::Error for invalid parameters, naming the first.
  RobotController(std::string name, const ControllerParams& params);

  /// A new motion along `path` toward `target` ("" = none), stopping by itself within
  /// `stop_radius_m` of its end point (task::stopRadiusAgainstBody), or held by its filter --
  /// at contact with a body it ends against, or short by bodies beside it -- within
  /// `held_stop_radius_m` of it (task::stopRadius, task/body_geometry.h); the last
  /// one is forgotten, and what it may touch is none until setContacts(). Awaited by a robot
  /// queued behind it (MotionContacts::awaited_by), carrying nothing, it stops within
  /// `place_stop_radius_m` (task::stopRadiusAgainstBody; <= 0: `stop_radius_m`). Throws
  /// ddace::Error for an empty path or a non-finite point or radius.
  void start(const PlannedPath& path, const std::string& target, double stop_radius_m, double held_stop_radius_m,
             double place_stop_radius_m = 0);
  /// What the running motion may touch (decided for its step).
  void setContacts(MotionContacts contacts);
  /// Forgets the motion (stopped, replaced, e-stop): the controller is Idle.
  void cancel();

  /// One control cycle at `now_s` for the robot at `pose` (measured; `pose_stale`: the
  /// tracker's flag or a pose too old; `pose_age_s` how old it is) with body radius
  /// `radius_m`. `others`: every other body as tracked, `standing` set by the caller (no
  /// running motion); their touchable flags are set here. Idle: zero wheels.
  ControlOutput cycle(const Pose2D& pose, bool pose_stale, double pose_age_s, double radius_m,
                      std::vector<SafetyBody>& others, double now_s);

  bool running() const { return follower_.hasPath(); }
  const std::string& name() const { return name_; }
  const std::string& target() const { return target_; }
  const MotionContacts& contacts() const { return contacts_; }
  /// The running motion's end point (idle: the origin).
  Eigen::Vector2d endPoint() const { return follower_.endPoint(); }
  double progress() const { return follower_.progress(); }
  const ControllerParams& params() const { return params_; }

 private:
  ControlOutput end(ControlOutput out, MotionState state, std::string message);
  ControlOutput stale(ControlOutput out, const std::string& why, double now_s);
  /// Queued behind `whom` (MotionContacts::after), which is still on its way: the robot
  /// stands (zero wheels).
  ControlOutput waitFor(ControlOutput out, const std::string& whom);
  /// The motion is done (`message`); a carrier that pushes its load backs off it first.
  ControlOutput done(ControlOutput out, std::string message, const Pose2D& pose, double pose_age_s, double radius_m,
                     std::vector<SafetyBody>& others, double now_s);
  /// A carrier whose push is done backs off its load, turning to drive straight away from
  /// it, through its filter; done kPushBackOffM beyond contact, or where its filter holds it
  /// (it stays).
  ControlOutput backOff(ControlOutput out, const Pose2D& pose, double pose_age_s, double radius_m,
                        std::vector<SafetyBody>& others, double now_s);
  /// A carrier's load seen first in its motion: the route it pushes the load along, its
  /// path beyond the load (exec::loadRoute).
  void planLoadRoute(const SafetyBody& load);
  /// A carrier not behind its load: its path planned again round the load, on along the
  /// rest of the load's route (exec::routeOnFrom; led out first from beside a body standing
  /// in its run-up, exec::withRunUp; pushPathAlong), when its push just broke or the load is
  /// kPushReplanM from where the path was planned for. `standing`: the bodies standing as
  /// this cycle's push sees them (standingRound), gone round as the first plan went round
  /// those of exec::pushObstacles.
  void replanPush(const Pose2D& pose, const SafetyBody& load, double radius_m,
                  const std::vector<PushObstacle>& standing);

  std::string name_;
  ControllerParams params_;
  PathFollower follower_;
  SafetyFilter filter_;
  std::string target_;
  MotionContacts contacts_;
  double stop_radius_m_ = 0;                 ///< the motion's (start()), unless it ends beside one still moving
  double held_stop_radius_m_ = 0;            ///< the motion's (start())
  double place_stop_radius_m_ = 0;           ///< the motion's when others wait for it (start())
  double stale_since_s_ = -1;                ///< since when the motion waits on a stale pose (-1: not)
  Eigen::Vector2d push_planned_for_{0, 0};   ///< where the load was when the path was planned (NaN: not seen yet)
  std::vector<Eigen::Vector2d> load_route_;  ///< the route the load is pushed along (empty: not planned yet)
  bool was_pushing_ = false;                 ///< behind its load in the last cycle
  bool backing_off_ = false;                 ///< its push done: backing off its load (backOff())
  std::string done_message_;                 ///< the motion's, reported once backed off
};

}  // namespace ddace::exec
