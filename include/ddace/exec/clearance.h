// How close the bodies of a run came to each other, from their tracked positions: the
// smallest gap between any two discs (the closest approach) and every collision (two
// discs overlapping deeper than a tolerance for tracking noise, counted once per contact
// until they are again more than the tolerance apart). Two bodies placed one on the other when
// both are first seen (a load on its carrier: overlapping deeper than kPlacedOnM) are never
// measured against each other; two that touch then (a scene's start: the tracked positions of
// touching bodies overlap a little) are no collision until they have parted. Two bodies that came
// into contact while allowed to touch (AllowedContacts) are not measured while they touch --
// unless, no longer allowed (a later step), they overlap deeper than the tolerance: a robot
// that ended against a body and later shoves into it collides (PairContact, the one rule).
//
// Which bodies may touch while a step runs is exec/motion_contacts.h's (AllowedContacts), the
// execution monitor's run report and `ddace eval` with bodies (exec::BodiesExecution) alike.
//
// Used by the execution monitor (mock robots and the real table alike: it reads
// /ddace/entities). Owns: the measurement, the allowed contacts. Must not: know ROS or
// where positions come from. Units: metres, seconds; table frame.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <map>
#include <set>

#include <Eigen/Core>

#include "ddace/exec/motion_contacts.h"
#include "ddace/task/body_geometry.h"

namespace ddace::exec {

/// Two bodies overlapping deeper than this when first seen were placed one on the other (a
/// load on its carrier, metres): they never collide. Less deep they touch -- each tracked
/// position carries up to task::kArrivalToleranceM of noise -- and collide as any two bodies.
inline constexpr double kPlacedOnM = 2 * task::kArrivalToleranceM;

/// The closest two bodies came (gap between their discs; negative = overlap).
struct ClosestApproach {
  double clearance_m = 1e9;  ///< 1e9 while fewer than two bodies were measured
  int a = -1, b = -1;        ///< entity indices, a < b
  double time_s = 0;
  Eigen::Vector2d at_a{0, 0}, at_b{0, 0};  ///< their centres then
};

/// Two bodies that came into contact (or overlap): the moment it began.
struct BodyContact {
  double time_s = 0;
  int a = -1, b = -1;  ///< entity indices, a < b
};

/// The one rule of when two bodies' contact is a collision, for the run report
/// (ClearanceMeter) and `ddace eval` with bodies (BodiesExecution) alike. A pair that comes
/// within the tolerance while allowed to touch is touching-allowed: not measured until it
/// parts (gap > tolerance), or until, no longer allowed, it overlaps deeper than the
/// tolerance (a robot that ended against a body shoves it in a later step: a collision). A
/// pair apart that touches while not allowed collides, once until it parts.
class PairContact {
 public:
  /// One observation: `gap` (metres, negative = overlap); `contact`: the two touch now as
  /// the caller detects contact (an overlap deeper than the tolerance; a Box2D contact that
  /// began); `allowed`: whether they may touch now (AllowedContacts::allowed). Returns true
  /// when a collision begins.
  bool update(double gap, bool contact, bool allowed, double tolerance_m);
  /// Whether the pair's gap counts for the closest approach now (not while touching-allowed,
  /// nor while allowed).
  bool measured(bool allowed) const { return !allowed && state_ != State::TouchingAllowed; }
  /// The two touch by design from now on (a carrier and the load it set down).
  void touchAllowed() { state_ = State::TouchingAllowed; }
  /// The two touch when first seen (a scene's start): no collision until they have parted.
  void touchingAtStart() { state_ = State::Collided; }

 private:
  enum class State : char { Apart, Collided, TouchingAllowed };
  State state_ = State::Apart;
};

class ClearanceMeter {
 public:
  /// `radii`: every entity's disc radius in the task's order (0 = no body: a goal).
  /// `overlap_tolerance_m`: an overlap deeper than this is a collision (tracking noise
  /// makes touching bodies overlap a little).
  explicit ClearanceMeter(std::vector<double> radii, double overlap_tolerance_m = 0.002);
  /// Every entity's position at `time_s` (a non-finite one = not known). Two bodies that
  /// touch while `allowed` (the running step's) are not measured until they are apart
  /// again, or overlap beyond the tolerance when no longer allowed (PairContact).
  void update(double time_s, const std::vector<Eigen::Vector2d>& positions, const AllowedContacts& allowed = {});
  const ClosestApproach& closest() const { return closest_; }
  const std::vector<BodyContact>& collisions() const { return collisions_; }
  const std::vector<std::pair<int, int>>& loadedPairs() const { return loaded_; }

 private:
  enum class Seen : char { Unseen, Tracked, Loaded };
  std::vector<double> radii_;
  double tolerance_m_;
  std::vector<Seen> seen_;             ///< a * n + b for a < b
  std::vector<PairContact> contacts_;  ///< a * n + b for a < b
  ClosestApproach closest_;
  std::vector<BodyContact> collisions_;
  std::vector<std::pair<int, int>> loaded_;
};

}  // namespace ddace::exec
