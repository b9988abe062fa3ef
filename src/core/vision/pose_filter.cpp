#include "ddace/vision/pose_filter.h"

#include <cmath>

namespace ddace::vision {

bool PoseFilter::consistent(const PlanarPose& a, double ta, const PlanarPose& b, double tb) const {
  const double dt = std::abs(tb - ta);
  const double dist = std::hypot(b.x - a.x, b.y - a.y);
  const double dyaw = std::abs(wrapAngle(b.yaw - a.yaw));
  return dist <= config_.max_speed_mps * dt + config_.gate_margin_m && dyaw <= config_.max_yaw_rate_rps * dt + 0.2;
}

void PoseFilter::reset() {
  seen_ = false;
  outlier_run_ = 0;
  vx_ = vy_ = speed_mps_ = 0;
}

bool PoseFilter::update(const PlanarPose& m, double t) {
  if (!seen_) {
    pose_ = m;
    pose_.yaw = wrapAngle(m.yaw);
    seen_ = true;
    last_seen_ = t;
    outlier_run_ = 0;
    vx_ = vy_ = speed_mps_ = 0;
    velocity_samples_ = 0;
    return true;
  }
  if (!consistent(pose_, last_seen_, m, t)) {
    ++rejected_;
    // A run of outliers that agree with each other is the entity somewhere else.
    if (outlier_run_ > 0 && consistent(outlier_pose_, outlier_t_, m, t)) ++outlier_run_;
    else outlier_run_ = 1;
    outlier_pose_ = m;
    outlier_t_ = t;
    if (outlier_run_ < config_.reacquire_after) return false;
    pose_ = m;
    pose_.yaw = wrapAngle(m.yaw);
    last_seen_ = t;
    outlier_run_ = 0;
    vx_ = vy_ = speed_mps_ = 0;
    velocity_samples_ = 0;
    return true;
  }
  outlier_run_ = 0;
  // After a gap, the old pose says little about the new one: take the measurement.
  const bool gap = t - last_seen_ > 0.25;
  const double gp = gap ? 1.0 : config_.position_gain;
  const double gy = gap ? 1.0 : config_.yaw_gain;
  const double dt = t - last_seen_;
  if (gap || dt <= 0) {
    vx_ = vy_ = 0;
    velocity_samples_ = 0;
  } else {
    // Smoothed over a few frames (one frame's difference is mostly detection noise
    // for a slow robot); the first difference is taken as it is.
    constexpr double kVelocityGain = 0.3;
    const double g = velocity_samples_++ == 0 ? 1.0 : kVelocityGain;
    vx_ += g * ((m.x - pose_.x) / dt - vx_);
    vy_ += g * ((m.y - pose_.y) / dt - vy_);
  }
  speed_mps_ = std::hypot(vx_, vy_);
  pose_.x += gp * (m.x - pose_.x);
  pose_.y += gp * (m.y - pose_.y);
  pose_.yaw = wrapAngle(pose_.yaw + gy * wrapAngle(m.yaw - pose_.yaw));
  last_seen_ = t;
  return true;
}

}  // namespace ddace::vision
