// Which bodies a motion may touch: the one answer, decided once per step from the step's
// end points (motionContacts), in ROS as in simulation. The robot's controller gives it to
// its safety filter (exec::RobotController::setContacts); the collision count of `ddace
// eval` with bodies and of the execution monitor's run report read the same answer
// pairwise (AllowedContacts): a contact one motion may make is no collision, any other is.
//
// A motion may touch its target; a carrier its load -- an object whose motion has the
// same step, action and target, within task::togetherDistance of it when the step begins
// (a load of two carriers belongs to the first); and the bodies its end point touches, or
// its load's end point touches (exec::endsAgainst with the filter's reach, at the bodies'
// final positions: one standing there, or ending there this step, not one only passing
// by) -- each only while that body is at the end point: two robots bound for one goal
// keep apart on the way.
//
// A robot is queued behind another when its end point does not reach its target (a body)
// but touches the end point of a robot of its step bound for the same target, nearer it
// (a place behind another at the body they meet at): it stands where it is until that one
// stands (exec::RobotController), so it never seals the way in of the one whose place is
// nearer by getting there first. The places of a meeting are taken from the inside out.
// Onto a flat goal (no body to be reached past), a robot is queued behind one bound for the
// same goal when its place lies on that one's way in (its planned path) and not the other way round
// -- unless it already stands on that way (waiting would unseal nothing). A robot others
// wait for ends at its own place (within the stop tolerance, not the stop radius): stopping
// short on its way in, it would stand in the place of the one waiting for it.
//
// A robot whose place is beside another's of its meeting stops short of it (within the stop
// radius) while that one is on its way, leaving its way in open -- only where stopping short
// leaves the meeting's places open: where the point of its way at the stop radius
// (task::stopRadius) would stand against (exec::endsAgainst, the filter's reach) the place of
// another robot of its meeting that its own place leaves clear, that one could not come to
// its place, and it ends at its own place, stopping short for none.
//
// Owns: the rule. Must not: know ROS, or decide where motions end (task/end_point.h).
// Units: metres; table frame.
#pragma once

#include <limits>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/safety_filter.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

/// What a motion may touch, decided once per step from the step's end points.
struct MotionContacts {
  std::string load;  ///< the object it carries ("" = none)
  /// The table carries the load in front of its carrier once met (TableSimulator::carry with
  /// loads_ride: the mock robots by default) instead of leaving it to be pushed (the real
  /// table, its simulation): no push steering (exec/push_path.h's pushWheels).
  bool load_rides = false;
  Eigen::Vector2d load_end{0, 0};  ///< where the load ends
  /// Where the load stood when this was decided (NaN: unknown): its carrier's push was
  /// planned for it there (exec::RobotController plans again when it lies elsewhere).
  Eigen::Vector2d load_at{Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN())};
  std::set<std::string> ends_against;       ///< bodies its end point touches (SafetyBody::touchable)
  std::set<std::string> load_ends_against;  ///< bodies the load's end point touches (load_touchable)
  /// The robots it is queued behind (see motionContacts): it stands where it is until each
  /// of them stands (arrived, or stopped).
  std::set<std::string> after;
  /// The robots of its step that need it at its own place: queued behind it (their `after`
  /// names it; they wait for it to stand), or of its meeting with a place its own leaves
  /// clear and its stop short would not (see motionContacts; then `beside` is empty). It
  /// ends at its own place, within the stop tolerance (exec::RobotController): stopping
  /// short it would stand in such a robot's place.
  std::set<std::string> awaited_by;
  /// The robots of its step whose end points touch its own and that are not in `awaited_by`
  /// (places side by side): while one of them is on its way, it stops within the held
  /// stop radius, leaving that one's way in open (exec::RobotController).
  std::set<std::string> beside;
};

/// A body as a step's motions see it when the step begins.
struct BodyAtStart {
  std::string name;
  Eigen::Vector2d position{0, 0};        ///< where it is now
  Eigen::Vector2d final_position{0, 0};  ///< where it ends this step: its motion's end point, else `position`
  double radius_m = 0;
  bool object = false;
  /// Its motion's step, action and target (step -1: no motion), for an object that may
  /// be the robot's load.
  int step = -1;
  std::string action, target;
  std::vector<Eigen::Vector2d> way;  ///< its motion's planned path (empty: unknown)
};

/// What a robot's motion (`step`, `action`, `target`, ending at `end_point`) may touch,
/// decided when its step begins with the robot at `position` (see the header comment);
/// `arrival_radius_m`: the task's (task::togetherDistance); `way`: the motion's planned path
/// (empty: unknown). The one answer of the path follower node, the simulator with bodies
/// and the collision count.
MotionContacts motionContacts(const Eigen::Vector2d& position, double radius_m, const Eigen::Vector2d& end_point,
                              int step, const std::string& action, const std::string& target,
                              const std::vector<BodyAtStart>& bodies, double reach_m, double arrival_radius_m,
                              const std::vector<Eigen::Vector2d>& way = {});

/// A motion of a step and what it may touch (motionContacts), by entity index.
struct DecidedMotion {
  int entity = -1;
  int target = -1;  ///< -1: none
  Eigen::Vector2d end{0, 0};
  MotionContacts contacts;
};

/// The pairs of bodies allowed to touch while a step runs -- their contact is no collision
/// and their gap no clearance -- read from what each of the step's motions may touch
/// (motionContacts): a motion and its target, a carrier and its load, a motion (or its
/// load) and a body its end point touches while that body is at the end point.
class AllowedContacts {
 public:
  /// None: every contact counts.
  AllowedContacts() = default;
  /// From the step's motions as decided (`names`, `radii`: every entity's; 0 = no body).
  /// Throws ddace::Error for a motion naming an entity outside them.
  AllowedContacts(const std::vector<std::string>& names, const std::vector<double>& radii,
                  const std::vector<DecidedMotion>& motions, double reach_m);
  /// Decided here (motionContacts for every motion of the step): `tokens`: the step's;
  /// `starts`: every entity's position when the step begins; `ends`: every entity's
  /// position at the end of the step (a motion's end point, else where it stands;
  /// non-finite = unknown); `moves`: whether the entity has a motion this step; `radii`:
  /// every entity's disc (0 = no body); `reach_m`: the safety filter's SafetyParams::endsAgainstReachM(). Throws
  /// ddace::Error when the sizes differ or a token names an entity outside them.
  AllowedContacts(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                  const std::vector<Eigen::Vector2d>& starts, const std::vector<Eigen::Vector2d>& ends,
                  const std::vector<bool>& moves, const std::vector<double>& radii, double reach_m);
  /// Whether `a` (at `pa`) and `b` (at `pb`) may touch now.
  bool allowed(int a, int b, const Eigen::Vector2d& pa, const Eigen::Vector2d& pb) const;

 private:
  struct EndsAgainst {
    int entity;  ///< whose end (a motion's, or its load's)
    Eigen::Vector2d end;
    int other;
  };
  std::set<std::pair<int, int>> exempt_;  ///< (a, b), a < b: a motion and its target, a carrier and its load
  std::vector<EndsAgainst> ends_against_;
  std::vector<double> radii_;
  double reach_m_ = 0;
};

/// The running step's allowed contacts, as its segments arrive one by one within
/// milliseconds (the execution monitor): decided again from the step's motions so far at
/// each.
class StepContacts {
 public:
  /// `radii`: every entity's disc (0 = no body); `reach_m`: the path followers' SafetyParams::endsAgainstReachM().
  StepContacts(task::TaskSpec spec, std::vector<double> radii, double reach_m);
  /// The segment of `entity` (index) in `step` with `token`, ending at `end`; `at`: every
  /// entity's position now (table frame, metres; NaN = unknown). A new step forgets the
  /// last one's contacts first. Throws ddace::Error naming both when the token is another
  /// entity's (the segment is not counted), or when the contacts cannot be decided (then
  /// none are allowed: every contact counts).
  void note(int step, int entity, const task::Token& token, const Eigen::Vector2d& end,
            const std::vector<Eigen::Vector2d>& at);
  /// A segment of `step` arrived (also one that cannot be noted): a new step forgets the
  /// last one's contacts.
  void beginStep(int step);
  const AllowedContacts& allowed() const { return allowed_; }

 private:
  task::TaskSpec spec_;
  std::vector<double> radii_;
  double reach_m_;
  int step_ = -1;
  std::map<int, std::pair<task::Token, Eigen::Vector2d>> ends_;  ///< the step's motions: token, end point
  AllowedContacts allowed_;
};

}  // namespace ddace::exec
