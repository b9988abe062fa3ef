// The geometry of bodies at the end of a motion: the one owner of when two bodies touch,
// when they are at one place, where a robot stops and when a motion has arrived
// (docs/task-format.md, "Bodies" and "Where a motion ends"). Every part reads them here:
// the end points (task/end_point.h), the controller and the simulators (exec), the
// coordinator, the labeller and the scene network.
//
// Contact: TaskSpec::contactDistance, the sum of two bodies' radii, 0 when either is no
// obstacle (a flat goal is driven onto, never touched).
//
// Radii about a motion's end point, each named for what it is:
//   - the *arrival radius* (task.yaml's arrival_radius): a motion counts as arrived when
//     the entity is within it (arrived());
//   - the *stop radius*: a robot bound for a flat goal stops by itself within it of its
//     end point -- the arrival radius less the stop tolerance (the tracking noise a
//     measured pose carries), so noise cannot leave a stopped robot outside it;
//   - a robot sent to a body (a robot, an object; carrying nothing) stops within the stop
//     tolerance of its end point (stopRadiusAgainstBody): its end point is where the
//     demonstrations stopped against that body (touching, 4 mm, 1 cm; task/end_point.h),
//     and it ends there within the tracking noise, not up to the stop radius (2.4 cm)
//     farther off -- except while a robot whose place is beside its own is still on its
//     way (exec::MotionContacts::beside): then within the stop radius, leaving that one's
//     way in open, where stopping short does; so does a robot, onto a flat goal too, that
//     another robot is queued behind or whose place it would stand against stopping short
//     (exec::MotionContacts::awaited_by): it would stand in that one's place;
//   - held by its safety filter at contact with a body it ends against, or short of its
//     end point by bodies beside it, a robot has arrived within the arrival radius less
//     the tolerance of it (stopRadius, not reduced: its true position is within the
//     arrival radius).
// And "at one place" (togetherDistance): contact plus the arrival radius.
//
// Goal conditions (task.yaml's goal_conditions) are judged within what bodies allow
// (goalConditionMet): "E at A within t" holds when E is within t of the nearest place its
// body can stand on its line to A -- A itself when nothing stands there, else where its body
// first clears every other obstacle (reachableDistance). A goal another robot stands on is
// reached at contact with it.
//
// Owns: these rules and their tolerance. Must not: decide where a motion ends (the end
// point rule does, task/end_point.h). Units: metres.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ddace/task/task_spec.h"

namespace ddace::task {

/// The tracking noise one reading of a pose may carry (metres), the least stop tolerance:
/// the coordinator counts a DONE this far outside the arrival radius (its
/// arrival_tolerance_m, whose default this is).
inline constexpr double kArrivalToleranceM = 0.005;

/// The stop tolerance of execution with tracking noise `noise_m` (std-dev of x and y):
/// three sigma, never less than kArrivalToleranceM.
double stopTolerance(double noise_m);

/// Where a robot stops by itself: within this of its end point (the stop radius). The
/// arrival radius less the tolerance, never less than half the arrival radius (a radius
/// within the noise itself).
double stopRadius(double arrival_radius, double tolerance = kArrivalToleranceM);

/// The stop radius of a motion toward a body (a robot, an object), carrying nothing: the
/// stop tolerance, never above `stop_radius` (stopRadius). Held at contact short of it, the
/// motion has arrived too (exec::endedAtContact).
double stopRadiusAgainstBody(double stop_radius, double tolerance);

/// A motion has arrived when `position` is within `arrival_radius` of its end point.
bool arrived(const Eigen::Vector2d& position, const Eigen::Vector2d& end_point, double arrival_radius);

/// How far apart entities `a` and `b` of `spec` may stand when one has arrived where a
/// motion toward the other ends, or both at one target (metres): "at one place". One
/// stopped short of the other is within contact plus the arrival radius; two that arrived
/// on one goal are each within the radius of it, at most two radii apart. The larger of
/// the two. The scene network's "together" (docs/tgn.md) reads places with it, so a robot
/// stopped where the follower stops counts as at its load, as in demonstrations. Also the
/// reach of a ride: a load rides with its carrier when it starts within it.
double togetherDistance(const TaskSpec& spec, int a, int b);
/// The same from the two bodies' contact distance (TaskSpec::contactDistance) and the task's
/// arrival radius, metres.
double togetherDistance(double contact_m, double arrival_radius);
/// Whether entities `a` at `pa` and `b` at `pb` of `spec` are at one place: within
/// togetherDistance(spec, a, b) of each other. The one test of "together" for the
/// labeller, the scene network, the end points and the table simulator.
bool together(const TaskSpec& spec, int a, const Eigen::Vector2d& pa, int b, const Eigen::Vector2d& pb);

/// How near entity `entity` of `spec` can stand to entity `at` on its line to it (metres from
/// `at`), every entity at `positions` (table frame; a non-finite position stands nowhere):
/// the least distance s >= 0 along the ray from `at` toward `entity` at which the body of
/// `entity` overlaps no other obstacle but `at` itself (contact is no overlap). 0 when
/// `entity` is no obstacle, or stands on `at`. `at`'s own body does not count: a condition
/// between two bodies is read as their centre distance. Throws ddace::Error when
/// `positions` is not one per entity or an index is outside it.
double reachableDistance(const TaskSpec& spec, int entity, int at, const std::vector<Eigen::Vector2d>& positions);

/// Whether `condition` holds with every entity of `spec` at `positions`: its entity is
/// within its tolerance of where its body can stand nearest its `at` (reachableDistance),
/// that is |E - A| - reachableDistance <= tolerance. False when either entity is unknown
/// to `spec` or its position is not finite. The one judge of `ddace eval`, the coordinator
/// and the run report. Throws ddace::Error when `positions` is not one per entity.
bool goalConditionMet(const TaskSpec& spec, const GoalCondition& condition,
                      const std::vector<Eigen::Vector2d>& positions);

}  // namespace ddace::task
