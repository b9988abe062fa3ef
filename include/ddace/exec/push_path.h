// How a robot moves a load it carries: it pushes it. A box has no wheels and a Hamster
// cannot hold one, so the carrier goes round the load to its far side from where the load
// ends, then drives straight through where the load stands toward its own end point, the
// load in front of it:
//
//        carrier
//           \  round the load, kPushClearanceM clear of contact
//            )
//   run-up o-(-- load ======================> load's end point
//            behind it          the push       (the carrier's end point behind it)
//
// Bodies standing in the way (robots that stay, boxes nobody moves) are gone round: the
// load's route from where it stands to its end is straight where that is free of them
// (kPushPassM beyond contact, for the load and for the carrier behind it), else the shortest
// way round them; the carrier goes round the load the way that is free to behind it,
// where the push first heads it, then drives the route, the load in front of it. Where a
// body stands in that run-up (a relay's giver, behind the box it handed on), the load is
// pushed out from beside it first, then on to its end.
//
// The load's end point decides the direction of the push and where it stops: the carrier
// ends behind it at their contact distance (on the route's last leg; where the learned end
// point of the carrier puts it elsewhere, the route wins). The planned path of the carrier
// (the learned primitive's) says how a robot moves alone; a push goes straight from corner
// to corner, the one way a disc moves a disc without losing it. The carrier's path is the
// push's plan: its controller steers the load along the path beyond the load (loadRoute),
// bends and all, and plans again from that route when the load slides off it.
//
// One rule for everything that drives a carrier: the coordinator's segments (ROS graph:
// mock robots, the real table, its simulation) and the closed-loop simulator.
//
// Owns: the carrier's path when it moves a load. Must not: decide end points
// (task/end_point.h) or who carries what (task::ridingLoad). Units: metres, table frame.
#pragma once

#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

/// How far outside contact with its load the carrier goes round it (metres): its run-up
/// before touching the load, more than the path follower's lookahead needs to line up.
inline constexpr double kPushClearanceM = 0.06;
/// The arc round the load is drawn in steps of this angle (radians).
inline constexpr double kPushArcStepRad = 0.2;
/// A carrier pushes (pushWheels()) while its load is within this angle of the push
/// direction, seen from the carrier, and within kPushClearanceM / 3 of contact (radians).
inline constexpr double kPushConeRad = M_PI / 4;
/// How far the carrier over-steers the load's side drift (pushWheels()): a disc pushed off
/// its centre slides sideways, so the carrier heads as far past the contact line, the other
/// way, as the load has drifted from its push direction; at most kMaxPushLeadRad.
inline constexpr double kPushLead = 1.0;
inline constexpr double kMaxPushLeadRad = M_PI / 3;
/// A pushed load heads for its route this far ahead of itself (metres).
inline constexpr double kPushLookaheadM = 0.2;
/// A carrier not pushing its load plans its push again from where things are once the load
/// lies this far from where its path was planned for (metres): the load slid off its front,
/// or something else moved it.
inline constexpr double kPushReplanM = kPushClearanceM / 3;
/// A push planned again has a point every this many metres.
inline constexpr double kPushPathSpacingM = 0.005;
/// Its push done, a carrier backs off its load until this far beyond their contact: out of
/// its reach (pushWheels), still at one place with it (task::together). A robot is wider
/// than a box, so a carrier left touching its load stands in the way of anyone pushing the
/// load on past it (a relay's receiver); backed off, it leaves room.
inline constexpr double kPushBackOffM = kPushClearanceM / 3;

/// How far beyond contact a push passes a standing body (metres): the safety filter's margin
/// and room for the load's drift off its route.
inline constexpr double kPushPassM = 0.03;
/// A body the load or its carrier stands or ends beside (within its reach) is passed this
/// far beyond contact (metres), the safety filter's margin, and never nearer than it is there.
inline constexpr double kPushNearPassM = 0.01;
/// A body standing during a push: the carrier and its load keep their centres `reach_m`
/// from its centre (their contact distance with it + kPushPassM).
struct PushObstacle {
  Eigen::Vector2d centre{0, 0};
  double reach_m = 0;
};

/// The path of a carrier at `from` that pushes a load standing at `load` (their contact
/// distance `contact_m`) until the load is at `load_end`, round the bodies `standing`: the
/// load's route (pushRoute), round the load at contact + kPushClearanceM to behind it,
/// where the push first heads it along the route (the shorter way, unless only the longer one is free of `standing`;
/// with `push_from_behind`, not at all from where a push may start, pushMayStartHere),
/// then along the route to behind the load's end point at contact on its last leg (the
/// carrier's end point: the load's end decides where the carrier stops), `points` points
/// evenly spaced by arc length (at least 2). Where the run-up is taken (a body of `standing`
/// within the filter's margin, kPushNearPassM, of the carrier behind the load), the route
/// first leads the load out from beside that body, in the way that keeps the run-up free
/// and lets the carrier go round the load at the turn, whose carrier's path is shortest;
/// where the carrier stands boxed in at the load (withRunUp), it pushes the load out first.
/// A load already at its end point (within task::kMinApproachM) is not pushed: from
/// straight to `from`'s own end, `fallback_end`.
std::vector<Eigen::Vector2d> pushPath(const Eigen::Vector2d& from, const Eigen::Vector2d& load,
                                      const Eigen::Vector2d& load_end, double contact_m,
                                      const Eigen::Vector2d& fallback_end, int points,
                                      const std::vector<PushObstacle>& standing = {}, bool push_from_behind = true);

/// The route of a load pushed from `load` to `load_end` (corners, first `load`, last
/// `load_end`): straight where it keeps every body of `standing` at its reach, else the
/// shortest way round them (past corners kPushPassM beyond their reach). A body the load
/// stands or ends nearer to than its reach is passed kPushNearPassM beyond contact, no
/// nearer than it is there, on the leg leaving it or arriving at it; every leg between two
/// corners keeps each body at its reach. Straight when no way round is free.
std::vector<Eigen::Vector2d> pushRoute(const Eigen::Vector2d& load, const Eigen::Vector2d& load_end,
                                       const std::vector<PushObstacle>& standing);

/// A body standing at `centre` as a push goes round it: at its reach, the larger of its
/// contact distances with the carrier and with the load + kPushPassM. The one rule of a
/// push planned (pushObstacles) and planned again (exec::RobotController).
PushObstacle pushObstacle(const Eigen::Vector2d& centre, double carrier_contact_m, double load_contact_m);

/// The bodies standing while motion `step[i]` pushes its load `load` (an entity), the step
/// decided at `at` (every entity's position; a non-finite one is not known): every obstacle
/// (task::Footprint) but the carrier, its load, the step's movers and the loads riding with
/// them, at its reach for this carrier and load.
std::vector<PushObstacle> pushObstacles(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                                        int load, const std::vector<Eigen::Vector2d>& at);

/// The path of a carrier at `from` that pushes a load along `load_route` (corners, the
/// first where the load stands, the last its end point): round the load to behind it,
/// as pushPath, then along the route to behind the load's end on its last
/// leg, `points` points evenly spaced. Throws ddace::Error for a route of fewer than two
/// distinct points.
std::vector<Eigen::Vector2d> pushPathAlong(const Eigen::Vector2d& from, const std::vector<Eigen::Vector2d>& load_route,
                                           double contact_m, int points, const std::vector<PushObstacle>& standing = {},
                                           bool push_from_behind = true);

/// `load_route` (corners, the first where the load stands, the last its end point) where a
/// carrier at `from` can take its run-up behind the load; where a body of `standing` takes
/// it, a route that first leads the load out from beside that body, then on to its end
/// (as pushPath plans it; `load_route` when no way out is free). A carrier boxed in at its
/// load -- at contact with it, a body of `standing` within its reach, not behind the load
/// for `load_route` and no way round the load free of `standing` (the way out from the
/// load through the carrier passes that body nearer than it stands: the filter would let
/// it neither drive on nor turn) -- pushes the load out first, straight on along their
/// contact normal as far as it then goes round the load freely, then on to its end. The
/// one rule of a push planned and planned again (exec::RobotController).
std::vector<Eigen::Vector2d> withRunUp(const Eigen::Vector2d& from, std::vector<Eigen::Vector2d> load_route,
                                       double contact_m, const std::vector<PushObstacle>& standing);

/// The route a load follows when its carrier drives `carrier_path` (planned by pushPath for
/// the load at `planned_load`): the carrier's path beyond the point nearest `planned_load`,
/// from where the load stands now (`load`), then on to the load's end point `load_end`. A
/// push path runs through its load and on along the load's route (round the bodies
/// standing in the way), so the load follows its carrier's whole route, bends and all, not
/// only its last leg.
std::vector<Eigen::Vector2d> loadRoute(const std::vector<Eigen::Vector2d>& carrier_path,
                                       const Eigen::Vector2d& planned_load, const Eigen::Vector2d& load,
                                       const Eigen::Vector2d& load_end);

/// The rest of `route` for a load now at `load` (off it: slid, or moved): from the load
/// straight to the route kPushLookaheadM ahead of where it stands along it (where
/// pushWheels heads it), then on along the route. The push planned again follows it.
std::vector<Eigen::Vector2d> routeOnFrom(const std::vector<Eigen::Vector2d>& route, const Eigen::Vector2d& load);

/// Whether a carrier at `carrier`, its load at `load` (contact distance `contact_m`) to be
/// pushed along `route` (loadRoute), may start its push from where it stands: within
/// kPushClearanceM / 3 of contact and kPushConeRad of behind the load from where the push
/// heads it (pushAim), and the load, driven first along their contact normal (before the
/// over-steer turns it), not run into the reach of a body of `standing` kPushNearPassM
/// deeper than a push straight where it should head (kPushClearanceM of either; a body the
/// load stands within the reach of is passed kPushNearPassM beyond contact, no nearer than
/// it is). Elsewhere the carrier
/// goes round the load to behind it first: a receiver beside a relay's giver, its contact
/// normal pointing at the giver, would shove the box into it.
bool pushMayStartHere(const Eigen::Vector2d& carrier, const Eigen::Vector2d& load,
                      const std::vector<Eigen::Vector2d>& route, double contact_m,
                      const std::vector<PushObstacle>& standing);

/// One control cycle of a carrier pushing its load.
struct PushCommand {
  WheelSpeeds wheels;
  bool load_arrived = false;  ///< the load reached its end point: the carrier is done
};

/// Steering a pushed load along its route (loadRoute; its last point the load's end point)
/// from the measured poses: the load heads for its route kPushLookaheadM ahead of where it
/// stands along it; the carrier at `carrier` (contact distance `contact_m` with its load at
/// `load`) heads along their contact line, turned by kPushLead of the load's drift from
/// where it should head, at the path follower's speeds (`gains`: cruise, slowdown by the
/// load's distance to its end, turn limits), slowed in proportion to that drift (standing,
/// turning only, at kMaxPushLeadRad): pushed on at full speed, a load drifting off its route is
/// dragged on off it faster than the over-steer turns their contact back. Nothing where the push may not start
/// (pushMayStartHere, round the bodies `standing`): it follows its path, round the load.
/// A push already under way (`pushing`: it pushed in the last cycle) holds while
/// the load drifts less than kMaxPushLeadRad, as far as the over-steer can bring it back,
/// rather than breaking off at the edge of the cone. The load has arrived once it is past its end point along the
/// route's last leg (the carrier stops there: the load's end point, not the carrier's, ends the push).
std::optional<PushCommand> pushWheels(const Pose2D& carrier, const Eigen::Vector2d& load,
                                      const std::vector<Eigen::Vector2d>& route, double contact_m,
                                      const FollowerGains& gains, bool pushing = false,
                                      const std::vector<PushObstacle>& standing = {});

/// Whether a carrier at `carrier` stands behind its load at `load`, at any distance: the
/// load, seen from the carrier, within kPushConeRad of where pushWheels heads it along
/// `route`, or already past its end point. Only from there may the carrier touch its load
/// (exec::RobotController): a carrier that runs into its load from the side shoves it off
/// its route.
bool behindLoad(const Eigen::Vector2d& carrier, const Eigen::Vector2d& load, const std::vector<Eigen::Vector2d>& route);

/// What the motion `step[i]` pushes when its step is decided at `decided` (every entity's
/// position): the entity index of its load (task::ridingLoad), or nothing.
std::optional<int> pushedLoad(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                              const std::vector<Eigen::Vector2d>& decided);

/// The path motion `step[i]` drives, its step decided at `decided` with its bodies ending
/// at `ends` (every entity's, task::stepEndPositions): a carrier that pushes a load
/// (pushedLoad) goes round the load and pushes it to the load's end (pushPath from the
/// start of `planned`, as many points, ending behind the load's end point); any other
/// motion drives `planned`. The simulator plans a step's paths with it, as the coordinator
/// does for the robots.
std::vector<Eigen::Vector2d> drivenPath(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                                        const std::vector<Eigen::Vector2d>& decided,
                                        const std::vector<Eigen::Vector2d>& ends, std::vector<Eigen::Vector2d> planned);

/// Where a carrier's motion is judged -- where it stands when done -- that moved its load,
/// planned to the load's end point `load_end` with the carrier stopping at `push_end` (its
/// path's last point, drivenPath: at contact behind the load), the load now at `load_at`
/// (where it ended; `load_end` when the motion is planned). A carrier whose load rides
/// (`loads_ride`) stays at `push_end`, the load going on alone to its end. One that pushes
/// stops where its load does (the load's arrival ends the push): behind where the load
/// ended as `push_end` is behind `load_end`, backed off kPushBackOffM farther straight
/// away from it (RobotController::backOff). Whether the load is on its end point is the
/// load's own motion's to judge. The one rule of the simulator and the coordinator.
Eigen::Vector2d carrierEnd(const Eigen::Vector2d& push_end, const Eigen::Vector2d& load_end,
                           const Eigen::Vector2d& load_at, bool loads_ride);

}  // namespace ddace::exec
