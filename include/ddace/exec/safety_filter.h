// The collision-avoidance safety filter between a robot's path follower and its wheels.
//
// Each robot runs its own filter from the tracked poses of the bodies around it (no
// central planner). The filter changes the follower's command as little as possible so
// that the robot's body stays at least `margin_m` beyond contact with every other body
// (robots, objects; goals are flat and drive-on), except its motion's own target, which
// it may touch (docs/execution.md, "Collision avoidance").
//
// How: a control barrier function on a point `projection_m` ahead of the axle (the
// Robotarium's unicycle barrier certificates). That point moves like a single integrator
// (p' = v e + w l e_perp), so keeping p at least contact + margin + l from a neighbour's
// centre keeps the bodies at least contact + margin apart. Per neighbour j, with
// h = |p - c_j| - (r_i + r_j + margin + l) and n the unit vector from c_j to p:
//   n . p'  >=  -share * gain * h       (share 1/2 for a robot on its way, which runs
//                                        its own filter and takes the other half; 1 for
//                                        a standing one, which does not move away, and
//                                        for an object)
// The right side is never above 0, so a pair already inside the margin (a start scene,
// a pushed robot) may separate but never close in; nearer contact than margin + l the
// disc's own centre gets the same constraint at half the margin (x' = v e), so a robot
// leaving a body it touches turns on the spot first instead of grazing it, and two robots
// pressed together within the margin are not drifted into contact by the tracking noise
// (a measured gap wider than the true one let them close in). The motion's
// target (and a body marked touchable: a body the motion's end point touches) gets the
// same constraint on the centres at contact distance. A carried load is part of the
// robot's body: its centre q, rigidly ahead of the axle, moves as q' = v e + w (q - x)^perp,
// and gets the same constraint per neighbour on its own disc. Together with the
// wheel limits these are half-planes in (v, l w); the least change of (v, l w) -- equal to
// the least change of p' -- is a quadratic programme in two variables, solved exactly by
// enumerating active sets (the command itself, each constraint's line, each vertex).
// Standing still always satisfies every constraint, so the programme is never
// infeasible.
//
// Held: a robot whose command the filter keeps changing and that does not advance
// `progress_m` along its path. Held for `resolve_after_s`, it goes around the body nearest
// to holding it or its load (carrier and load go round as one body) for the next
// `resolve_after_s`: a moving body keeping it on the left (every robot turns the same way,
// so two robots face to face pass each other, and a crowd crossing one spot turns round it
// and clears one robot after another), a standing one (SafetyBody::standing) on the side
// the robot's command turns to, the shorter way to its end point (the right-hand rule on a
// tie); the side is decided once per body while the robot is held (a command pointing at
// the body would flip it with the noise, back and forth round it). Standing bodies it
// cannot pass between (gaps narrower than its body with the filter's clearance either
// side: robots ringing the one they met at, a row, a queue) are one group: a group in its
// way (none of it a body its motion ends at) it passes by the group's edge, the one its
// command turns least to, heading past that edge as it sees it (round one body of the
// group it was led into the too-narrow gap next to it and held there; a carrier, whose
// load is turned by a lever and cannot head straight past an edge it touches, follows the
// group's outline to that edge, round one body after the other on the side decided for the
// group, the group and its edges taken for the disc held -- its load's or its own -- and
// the side kept whichever of the two the group holds next); a group it ends at,
// or one all round it (no edge), it goes round body by body -- except a group lying all
// round it that it does not end at (a met robot inside the ring of robots that met it, its
// way on through them): it leaves by the widest gap between two of them that its disc
// passes a margin off each (wayOut: behind or beside it as much as ahead), those bodies
// holding its disc, not the point ahead, a margin off while it does (the point has no room
// in such a gap), then passes the group by its edge.
//
// Deadlock: held while neither the robot nor any body holding it moves `progress_m` for
// `deadlock_after_s` (frozen: boxed in, held off its end point; a robot passing a group by
// its edge moves, leaving its path a while, and is not frozen), or held without advancing
// along its path for `wait_limit_s` while they move (a crowd that never clears, robots
// circling each other, a group it cannot get round). A held robot whose holders move
// waits its turn: it is not deadlocked, and stopping it would leave one more body in the
// others' way. The filter then reports the deadlock naming the robot and the bodies
// holding it (the caller stops the robot and reports it): every body whose constraint
// shaped the command, or that it went round, since it last advanced -- not only those
// active in the cycle the clock runs out in (going round, none is).
//
// Fail safe (when enabled): its own pose or a body within `range_m` older than `pose_max_age_s` (or
// marked stale) -> zero wheels and a report naming the stale body.
//
// Owns: the barrier constraints, the QP, blocked/deadlock timing. Must not: know ROS,
// read a clock (time comes in), or decide where a motion ends (the follower does).
// Units: metres, radians, seconds, m/s; table frame.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/diff_drive.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

struct SafetyParams {
  bool enabled = true;             ///< false: commands pass through (measurements of the unfiltered law)
  double margin_m = 0.01;          ///< clearance kept beyond contact between two bodies
  double projection_m = 0.01;      ///< the controlled point lies this far ahead of the axle
  double barrier_gain_hz = 3.0;    ///< how fast a gap may close: at most gain x (gap beyond the margin) per second
  double range_m = 0.25;           ///< bodies whose centres are farther than this are ignored
  double pose_max_age_s = 0.15;    ///< a pose older than this (a tracker frame is 33 ms) is stale
  double blocked_fraction = 0.25;  ///< filtered point speed below this fraction of the nominal = blocked
  double resolve_after_s = 0.5;    ///< held this long: go around the nearest body for as long
  double deadlock_after_s = 5.0;   ///< held, neither it nor a body holding it moving, this long: a deadlock
  double wait_limit_s = 20.0;      ///< held without progress this long while the bodies holding it move: a deadlock
  double progress_m = 0.02;        ///< advancing this much along the path is progress
  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
  /// How far beyond contact the filter holds a robot's centre off a body beside it: the
  /// barrier keeps the point projection_m ahead of the axle contact + margin off the body,
  /// so a body square to the robot's heading holds it margin + projection off (one ahead
  /// of it, margin + 2 projection). A body ending nearer than this to touching a motion's
  /// end point is one the motion ends against (endsAgainst): kept at the margin, it would
  /// hold the robot off its end point (ends turned about one target beside each other,
  /// task::kEndTurnGapM: robots ringing the one they meet at).
  double endsAgainstReachM() const { return margin_m + projection_m; }
};

/// Calls `visit(name, field)` for every field, by the name config/execution.yaml gives it
/// (path_follower/safety): the one list the ROS parameters and `ddace eval --config` read.
template <typename Visit>
void visitParams(SafetyParams& p, Visit&& visit) {
  visit("enabled", p.enabled);
  visit("margin_m", p.margin_m);
  visit("projection_m", p.projection_m);
  visit("barrier_gain_hz", p.barrier_gain_hz);
  visit("range_m", p.range_m);
  visit("pose_max_age_s", p.pose_max_age_s);
  visit("blocked_fraction", p.blocked_fraction);
  visit("resolve_after_s", p.resolve_after_s);
  visit("deadlock_after_s", p.deadlock_after_s);
  visit("wait_limit_s", p.wait_limit_s);
  visit("progress_m", p.progress_m);
}

/// A body the filter must keep clear of, as tracked.
struct SafetyBody {
  std::string name;
  Eigen::Vector2d position{0, 0};  ///< centre, table frame
  double radius_m = 0;             ///< disc around the centre
  bool robot = false;              ///< runs its own filter: takes half of each pair's constraint
  double age_s = 0;                ///< how old its pose is
  bool stale = false;              ///< the tracker says: never drive on it
  /// The motion may end touching it, as its target; the segment's `target` is always
  /// touchable.
  bool touchable = false;
  /// The robot's carried load (filter()'s `load`) may end touching it; the segment's
  /// `target` (the load's too: task::carriedLoad) always may.
  bool load_touchable = false;
  /// It stands still (an idle robot, an object without a motion): a go-round passes it on
  /// the side the robot's command turns to, not by the right-hand rule two moving robots
  /// share; and a standing robot takes no half of a pair's constraint (it does not move
  /// away), so the robot closes in on it at the full barrier rate.
  bool standing = false;
};

/// The body of an entity as the filter and the simulator see it: its disc radius and
/// whether others must keep off it (goals are flat: not an obstacle), from the task's
/// footprint (task::footprint, docs/task-format.md). The one place the execution reads it.
struct BodyShape {
  double radius_m = 0;
  bool obstacle = false;
};
BodyShape bodyShape(const task::Entity& e);
inline BodyShape bodyShape(const task::TaskSpec& spec, int i) {
  return bodyShape(spec.entities.at(i));
}

/// Whether a body at `position` with `radius_m` is one the motion ends against: the
/// robot's disc standing at the motion's `end_point` would be nearer than `reach_m`
/// (SafetyParams::endsAgainstReachM) to contact with it (the end-point rule ends a motion at
/// contact with a robot already on the goal, a queue's last robot, beside a robot bound for
/// the same one, ...). Such a body is touchable like the target (else the filter
/// would hold the robot a margin off its end point), and its contact with the robot is no
/// collision (exec/bodies_execution.h). Decided once, from where the bodies end (a step's
/// or a segment's start); while it runs, such a body is touchable only while it is at the
/// end point (endsAgainst from its current position): two robots bound for one goal keep
/// a margin on the way, and one that stopped short elsewhere is gone round, not pushed.
bool endsAgainst(const Eigen::Vector2d& end_point, double self_radius_m, const Eigen::Vector2d& position,
                 double radius_m, double reach_m);

/// What the filter decided for one control cycle.
struct SafetyCommand {
  WheelSpeeds wheels;                 ///< what goes to the wheels
  double v_mps = 0, w_radps = 0;      ///< the same as a twist
  bool modified = false;              ///< the nominal command was changed
  bool blocked = false;               ///< the nominal moves, the filtered command hardly does
  bool deadlock = false;              ///< blocked for deadlock_after_s: stop and report `reason`
  bool stale = false;                 ///< a pose was stale: wheels zero, `reason` names it
  std::vector<std::string> blocking;  ///< bodies whose constraints hold the robot (active ones)
  double clearance_m = 1e9;           ///< smallest gap between this body and another (beyond contact)
  std::string reason;                 ///< for stale and deadlock
  /// Held at contact by a body the motion may end against: blocked, every body holding it
  /// is its target or touchable, and it is within the margin of touching one of them
  /// (named here; "" otherwise). A motion toward a body ends at contact with it: near
  /// enough its end point, the caller counts it arrived (endedAtContact: it ended against
  /// this body, which stands a little off where the step decided it would be).
  std::string at_contact_with;
};

/// Whether the motion the filter holds (`c`) has arrived: held at contact with a body it
/// ends against (at_contact_with) and its measured distance to its end point within
/// `stop_radius_m`, the follower's own stop radius (task::stopRadius: the arrival radius less
/// the tracking noise) -- so that, as for a robot that stops by itself, its true position is
/// within the arrival radius. The one rule of the follower node and `ddace eval`.
bool endedAtContact(const SafetyCommand& c, double distance_to_end_m, double stop_radius_m);

class SafetyFilter {
 public:
  /// `wheel_base_m` and `max_wheel_speed_mps` as the robot's (FollowerGains);
  /// `max_turn_rate_radps` bounds the filtered yaw rate. Throws ddace::Error for invalid
  /// parameters.
  SafetyFilter(const SafetyParams& params, double wheel_base_m, double max_wheel_speed_mps, double max_turn_rate_radps);

  /// One control cycle at time `now_s` for robot `self_name` at `self` (pose `self_age_s`
  /// old) with body radius `self_radius_m`, the follower's `nominal` wheels, the arc
  /// length of its path covered so far (`progress_m`, never decreasing), the other
  /// `bodies` (self excluded) and the name of the motion's `target` ("" for none).
  /// `load`: the load the robot carries (it rides in front, exec::TableSimulator::ride),
  /// part of the robot's body: kept clear of every body as the robot's own disc is (except
  /// the target and the bodies marked load_touchable), its entry in `bodies` ignored.
  SafetyCommand filter(const std::string& self_name, const Pose2D& self, double self_radius_m, double self_age_s,
                       const WheelSpeeds& nominal, double progress_m, const std::vector<SafetyBody>& bodies,
                       const std::string& target, double now_s, const SafetyBody* load = nullptr);
  /// Forgets the blocked and deadlock clocks (a new segment, the robot idle).
  void reset() {
    resolve_until_s_ = stuck_since_s_ = waiting_since_s_ = -1;
    resolve_group_.clear();
    resolve_standing_ = false;
    leaving_.reset();
    held_by_.clear();
    holders_.clear();
  }
  const SafetyParams& params() const { return params_; }

 private:
  /// A way out between two standing bodies (wayOut).
  struct Gap {
    Eigen::Vector2d middle;  ///< halfway between the two bodies' edges
    Eigen::Vector2d out;     ///< unit normal of the line through them, away from the robot
  };
  SafetyParams params_;
  double wheel_base_m_, max_wheel_mps_, max_turn_radps_;
  double resolve_until_s_ = -1;             ///< the point goes round the nearest body until then
  double resolve_side_ = 1;                 ///< +1: keeping it on the left (the right-hand rule), -1: on the right
  std::vector<std::string> resolve_group_;  ///< the bodies resolve_side_ was decided for (standingGroup)
  bool resolve_standing_ = false;           ///< ... standing ones: gone round toward the group's edge
  std::optional<Gap> leaving_;              ///< ... all round it: the gap it leaves by first (wayOut)
  double stuck_since_s_ = -1;               ///< since when the filter holds the robot without progress
  double stuck_progress_m_ = 0;             ///< its progress then
  std::vector<std::string> held_by_;        ///< bodies that held it since then (named in a deadlock)
  double waiting_since_s_ = -1;             ///< since when neither it nor a body holding it has moved
  Eigen::Vector2d waiting_at_{0, 0};        ///< where the robot was then
  std::vector<std::pair<std::string, Eigen::Vector2d>> holders_;  ///< bodies holding it, where they were then

  SafetyCommand passThrough(const Pose2D& self, double self_radius_m, const WheelSpeeds& nominal,
                            const std::vector<SafetyBody>& bodies, const SafetyBody* load) const;
  /// Zero wheels, the clocks forgotten, `why` reported (a stale pose).
  SafetyCommand stop(const WheelSpeeds& nominal, std::string why);
  /// The robot's own name, its load's or a body's in range whose pose is stale; "" if none.
  std::string staleName(const std::string& self_name, const Pose2D& self, double self_age_s,
                        const std::vector<SafetyBody>& bodies, const SafetyBody* load) const;
  /// A disc on the table: the robot's body, or its load's.
  struct Disc {
    Eigen::Vector2d centre;
    double radius_m;
  };
  struct Scene;
  /// The command to filter: the nominal `z0`, or while going round, the command moving the
  /// held disc round `body` (`round_left` keeps it on the left) on the side decided for it.
  Eigen::Vector2d goRound(const Eigen::Vector2d& z0, const SafetyBody* body, bool of_load,
                          const Eigen::Vector2d& round_left, const Scene& scene, double now_s);
  /// Whether the side is decided for `body` (it is in the group decided for).
  bool decidedFor(const SafetyBody* body) const;
  void decideSide(const Eigen::Vector2d& z0, const SafetyBody* body, bool of_load, const Eigen::Vector2d& round_left,
                  const Scene& scene);
  /// `first` and the standing bodies the `held` disc (the robot's, or its load's) cannot
  /// pass between, linked through each other: gaps narrower than it with a margin either side.
  std::vector<const SafetyBody*> standingGroup(const SafetyBody& first, const Scene& scene, const Disc& held) const;
  /// The directions (table frame, radians) from the `held` disc past a group's right and
  /// left edges, the disc a margin off them.
  struct GroupEdges {
    double right_rad = 0, left_rad = 0;
  };
  GroupEdges groupEdges(const std::vector<const SafetyBody*>& group, const Disc& held) const;
  /// Where the robot leaves a group of standing bodies that lies all round it (none half a
  /// turn from the next, as seen from the robot): the widest gap between two neighbours, if
  /// its disc passes it with the margin either side. None: not enclosed, or no such gap. While it leaves, the
  /// group holds its disc, not the point ahead of it, a margin off: a ring's gap leaves the
  /// point no room either side, and the robot's way is its own go-round, not the path.
  std::optional<Gap> wayOut(const std::vector<const SafetyBody*>& group, const Scene& scene) const;
  /// The hold and deadlock clocks after a filtered cycle (`out` gets the deadlock);
  /// returns whether a go-round begins.
  bool trackHold(SafetyCommand& out, const std::string& self_name, const Eigen::Vector2d& x, double self_radius_m,
                 double progress_m, const std::vector<SafetyBody>& bodies, const std::string& going_round_of,
                 double now_s);
};

/// A half-plane a . z <= b in two variables.
struct HalfPlane {
  Eigen::Vector2d a{0, 0};
  double b = 0;
};
/// The point of the half-planes' intersection closest to `z0` (exact, by enumerating the
/// active sets). The intersection must not be empty (e.g. contain the origin); returns
/// the origin when no candidate is feasible (numerically empty).
Eigen::Vector2d closestFeasible(const Eigen::Vector2d& z0, const std::vector<HalfPlane>& constraints);

}  // namespace ddace::exec
