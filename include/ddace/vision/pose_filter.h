// Per-entity filtering of planar marker poses: outlier rejection, smoothing, a short
// hold through occlusion and a "stale" flag after it.
//
// Semantics a consumer relies on (and msg/Entity.msg publishes):
// - visible: a measurement was accepted in the last update;
// - while not visible, the pose is held at the last accepted value (never
//   extrapolated: a robot hidden by a hand may have stopped);
// - stale: no accepted measurement for longer than hold_s, or the entity's speed
//   estimate says it may have moved more than max_drift_m since (a held pose of a
//   fast object is wrong within frames), or never seen. Never drive on a stale pose.
// Times are seconds on one monotonic clock (image stamps); poses are table frame.
#pragma once

#include <algorithm>

#include "ddace/vision/table_frame.h"

namespace ddace::vision {

struct FilterConfig {
  double max_speed_mps = 1.0;      ///< faster apparent motion is an outlier; the tracker's
                                   ///< search regions grow at this speed too
  double max_yaw_rate_rps = 12.0;  ///< faster apparent turning is an outlier
  double gate_margin_m = 0.02;     ///< always-allowed jump (detection noise, frame jitter)
  int reacquire_after = 3;         ///< this many consecutive mutually consistent outliers
                                   ///< mean the entity really moved (picked up and put down)
  double hold_s = 1.0;             ///< keep the last pose this long without measurements
  double max_drift_m = 0.06;       ///< ... unless speed estimate x time unseen exceeds this
  double position_gain = 1.0;      ///< 1 = raw measurement; lower = smoother, but lags
                                   ///< by speed x frame period x (1 - gain) / gain
  double yaw_gain = 1.0;           ///< same for yaw
};

class PoseFilter {
 public:
  explicit PoseFilter(FilterConfig config = {}) : config_(config) {}

  /// Offers a measurement taken at time t. Returns true when accepted (inliers and
  /// reacquisitions), false when rejected as an outlier.
  bool update(const PlanarPose& measured, double t);
  /// Resets to "never seen".
  void reset();

  bool everSeen() const { return seen_; }
  /// Pose after the last accepted measurement (held while not visible).
  const PlanarPose& pose() const { return pose_; }
  double lastSeen() const { return last_seen_; }
  /// True when the last update() at time `t` was accepted.
  bool visibleAt(double t) const { return seen_ && last_seen_ == t; }
  /// True when never seen, not seen for longer than hold_s at time `t`, or
  /// driftAt(t) > max_drift_m.
  bool staleAt(double t) const { return !seen_ || t - last_seen_ > config_.hold_s || driftAt(t) > config_.max_drift_m; }
  /// How far the entity may have moved since its last measurement at its estimated
  /// speed (metres; 0 while visible).
  double driftAt(double t) const { return seen_ ? speed_mps_ * std::max(0.0, t - last_seen_) : 0.0; }
  /// Speed estimate from the accepted measurements (m/s; 0 after a gap or a reacquisition).
  double speed() const { return speed_mps_; }
  /// Number of measurements rejected so far.
  long rejected() const { return rejected_; }

 private:
  bool consistent(const PlanarPose& a, double ta, const PlanarPose& b, double tb) const;

  FilterConfig config_;
  bool seen_ = false;
  PlanarPose pose_;
  double last_seen_ = 0;
  long rejected_ = 0;
  double vx_ = 0, vy_ = 0, speed_mps_ = 0;
  long velocity_samples_ = 0;
  int outlier_run_ = 0;
  PlanarPose outlier_pose_;
  double outlier_t_ = 0;
};

}  // namespace ddace::vision
