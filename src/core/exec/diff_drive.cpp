#include "ddace/exec/diff_drive.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "ddace/common/error.h"

namespace ddace::exec {

void DiffDriveParams::validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    throw Error("diff-drive parameter '" + field + "' " + why);
  };
  if (!(rate_hz > 0) || !std::isfinite(rate_hz)) bad("rate_hz", "must be a positive number");
  if (!(wheel_base_m > 0) || !std::isfinite(wheel_base_m)) bad("wheel_base_m", "must be a positive number of metres");
  if (!(max_wheel_speed_mps > 0) || !std::isfinite(max_wheel_speed_mps))
    bad("max_wheel_speed_mps", "must be a positive speed in m/s");
  if (!(latency_s >= 0) || !std::isfinite(latency_s)) bad("latency_s", "must be >= 0 seconds");
  if (!(command_timeout_s >= 0) || !std::isfinite(command_timeout_s))
    bad("command_timeout_s", "must be >= 0 seconds (0 disables the watchdog)");
  if (!(position_noise_m >= 0) || !std::isfinite(position_noise_m)) bad("position_noise_m", "must be >= 0 metres");
  if (!(yaw_noise_rad >= 0) || !std::isfinite(yaw_noise_rad)) bad("yaw_noise_rad", "must be >= 0 radians");
}

WheelSpeeds twistToWheels(double v_mps, double w_radps, double wheel_base_m) {
  return {v_mps - w_radps * wheel_base_m / 2, v_mps + w_radps * wheel_base_m / 2};
}

Pose2D integrateUnicycle(const Pose2D& pose, double v_mps, double w_radps, double dt_s) {
  Pose2D out = pose;
  if (std::abs(w_radps) < 1e-9) {
    out.x += v_mps * dt_s * std::cos(pose.yaw);
    out.y += v_mps * dt_s * std::sin(pose.yaw);
  } else {
    const double yaw1 = pose.yaw + w_radps * dt_s;
    out.x += v_mps / w_radps * (std::sin(yaw1) - std::sin(pose.yaw));
    out.y -= v_mps / w_radps * (std::cos(yaw1) - std::cos(pose.yaw));
    out.yaw = wrapAngle(yaw1);
  }
  return out;
}

DiffDriveModel::DiffDriveModel(const DiffDriveParams& params, const Pose2D& initial)
    : params_(params), pose_(initial), rng_(params.seed) {
  params_.validate();
  pose_.yaw = wrapAngle(pose_.yaw);
}

void DiffDriveModel::command(const WheelSpeeds& wheels, double now_s) {
  const double lim = params_.max_wheel_speed_mps;
  auto clamp = [lim](double v) { return std::isfinite(v) ? std::clamp(v, -lim, lim) : 0.0; };
  pending_.push_back({now_s + params_.latency_s, now_s, {clamp(wheels.left_mps), clamp(wheels.right_mps)}});
}

void DiffDriveModel::step() {
  while (!pending_.empty() && pending_.front().effective_s <= time_s_ + 1e-12) {
    applied_ = pending_.front().wheels;
    last_command_s_ = pending_.front().given_s;
    pending_.pop_front();
  }
  // The watchdog runs on the robot, i.e. after the latency.
  if (params_.command_timeout_s > 0 && time_s_ - (last_command_s_ + params_.latency_s) > params_.command_timeout_s)
    applied_ = {};

  const double dt = 1.0 / params_.rate_hz;
  if (!stalled_) {
    const double v = wheel_gain_ * (applied_.left_mps + applied_.right_mps) / 2;
    const double w = wheel_gain_ * (applied_.right_mps - applied_.left_mps) / params_.wheel_base_m;
    pose_ = integrateUnicycle(pose_, v, w, dt);
  }
  time_s_ += dt;
}

void DiffDriveModel::setWheelGain(double gain) {
  if (!(gain > 0) || !std::isfinite(gain)) throw Error("wheel gain must be positive and finite");
  wheel_gain_ = gain;
}

Pose2D DiffDriveModel::measuredPose() {
  Pose2D p = pose_;
  if (params_.position_noise_m > 0) {
    p.x += params_.position_noise_m * normal_(rng_);
    p.y += params_.position_noise_m * normal_(rng_);
  }
  if (params_.yaw_noise_rad > 0) p.yaw = wrapAngle(p.yaw + params_.yaw_noise_rad * normal_(rng_));
  return p;
}

}  // namespace ddace::exec
