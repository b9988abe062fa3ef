// How close the bodies of a run came to each other, from their tracked positions: the
// smallest gap between any two discs (the closest approach) and every collision (two
// discs overlapping deeper than a tolerance for tracking noise, counted once per contact
// until they are again more than the tolerance apart). Two bodies that overlap when both are first seen (a load
// placed on its carrier) are never measured against each other.
//
// Used by the execution monitor (mock robots and the real table alike: it reads
// /ddace/entities). Owns: the measurement. Must not: know ROS or where positions come
// from. Units: metres, seconds; table frame.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace ddace::exec {

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

class ClearanceMeter {
 public:
  /// `radii`: every entity's disc radius in the task's order (0 = no body: a goal).
  /// `overlap_tolerance_m`: an overlap deeper than this is a collision (tracking noise
  /// makes touching bodies overlap a little).
  explicit ClearanceMeter(std::vector<double> radii, double overlap_tolerance_m = 0.002);
  /// Every entity's position at `time_s` (a non-finite one = not known).
  void update(double time_s, const std::vector<Eigen::Vector2d>& positions);
  const ClosestApproach& closest() const { return closest_; }
  const std::vector<BodyContact>& collisions() const { return collisions_; }
  const std::vector<std::pair<int, int>>& loadedPairs() const { return loaded_; }

 private:
  enum class Pair : char { Unseen, Apart, Touching, Loaded };
  std::vector<double> radii_;
  double tolerance_m_;
  std::vector<Pair> pairs_;  ///< a * n + b for a < b
  ClosestApproach closest_;
  std::vector<BodyContact> collisions_;
  std::vector<std::pair<int, int>> loaded_;
};

}  // namespace ddace::exec
