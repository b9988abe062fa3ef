#include "ddace/exec/path_follower.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "ddace/common/error.h"

namespace ddace::exec {

std::vector<double> progressOf(const std::vector<Eigen::Vector2d>& points) {
  std::vector<double> s(points.size(), 0.0);
  for (size_t i = 1; i < points.size(); ++i) s[i] = s[i - 1] + (points[i] - points[i - 1]).norm();
  const double total = s.empty() ? 0.0 : s.back();
  for (double& v : s) v = total > 0 ? v / total : 0.0;
  if (total > 0) s.back() = 1.0;
  return s;
}

PlannedPath resampleByArcLength(const PlannedPath& path, int n) {
  if (path.points.empty()) throw Error("cannot resample an empty path");
  if (n < 2) throw Error("a resampled path needs at least 2 points, got " + std::to_string(n));
  const bool sd = path.stddev_m.size() == path.points.size();
  const std::vector<double> s = progressOf(path.points);
  PlannedPath out;
  size_t k = 1;
  for (int i = 0; i < n; ++i) {
    const double u = static_cast<double>(i) / (n - 1);
    if (path.points.size() == 1 || s.back() == 0) {
      out.points.push_back(path.points.front());
      if (sd) out.stddev_m.push_back(path.stddev_m.front());
      continue;
    }
    while (k + 1 < s.size() && s[k] < u) ++k;
    const double len = s[k] - s[k - 1];
    const double f = len > 0 ? std::clamp((u - s[k - 1]) / len, 0.0, 1.0) : 0.0;
    out.points.push_back(path.points[k - 1] + f * (path.points[k] - path.points[k - 1]));
    if (sd) out.stddev_m.push_back(path.stddev_m[k - 1] + f * (path.stddev_m[k] - path.stddev_m[k - 1]));
  }
  return out;
}

void FollowerGains::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(v > 0) || !std::isfinite(v)) throw Error(std::string("follower gain '") + name + "' must be positive");
  };
  positive(cruise_speed_mps, "cruise_speed_mps");
  positive(lookahead_m, "lookahead_m");
  positive(slowdown_radius_m, "slowdown_radius_m");
  positive(rotate_in_place_rad, "rotate_in_place_rad");
  positive(heading_gain, "heading_gain");
  positive(max_turn_rate_radps, "max_turn_rate_radps");
  positive(search_window_m, "search_window_m");
  positive(stop_radius_m, "stop_radius_m");
  positive(wheel_base_m, "wheel_base_m");
  positive(max_wheel_speed_mps, "max_wheel_speed_mps");
  if (!(min_speed_mps >= 0) || min_speed_mps > cruise_speed_mps)
    throw Error("follower gain 'min_speed_mps' must be in [0, cruise_speed_mps]");
  if (cruise_speed_mps > max_wheel_speed_mps)
    throw Error("follower gain 'cruise_speed_mps' exceeds 'max_wheel_speed_mps'");
}

PathFollower::PathFollower(const FollowerGains& gains) : gains_(gains) {
  gains_.validate();
}

void PathFollower::setPath(const PlannedPath& path) {
  if (path.points.empty()) throw Error("path to follow has no points");
  for (size_t i = 0; i < path.points.size(); ++i)
    if (!path.points[i].allFinite())
      throw Error("path to follow has a non-finite coordinate at point " + std::to_string(i));
  points_ = path.points;
  cum_m_.assign(points_.size(), 0.0);
  for (size_t i = 1; i < points_.size(); ++i) cum_m_[i] = cum_m_[i - 1] + (points_[i] - points_[i - 1]).norm();
  total_m_ = cum_m_.back();
  s_m_ = 0;
  done_ = false;
}

void PathFollower::setStopRadius(double stop_radius_m) {
  FollowerGains g = gains_;
  g.stop_radius_m = stop_radius_m;
  g.validate();
  gains_ = g;
}

void PathFollower::clear() {
  points_.clear();
  cum_m_.clear();
  total_m_ = s_m_ = 0;
  done_ = false;
}

Eigen::Vector2d PathFollower::pointAt(double s_m) const {
  if (s_m <= 0 || points_.size() == 1) return points_.front();
  if (s_m >= total_m_) return points_.back();
  const size_t i = static_cast<size_t>(std::upper_bound(cum_m_.begin(), cum_m_.end(), s_m) - cum_m_.begin());
  const double len = cum_m_[i] - cum_m_[i - 1];
  const double f = len > 0 ? (s_m - cum_m_[i - 1]) / len : 0.0;
  return points_[i - 1] + f * (points_[i] - points_[i - 1]);
}

FollowerOutput PathFollower::compute(const Pose2D& pose) {
  FollowerOutput out;
  if (points_.empty()) return out;
  const Eigen::Vector2d p = pose.position();
  const Eigen::Vector2d goal = points_.back();
  out.distance_to_goal_m = (goal - p).norm();

  // Progress: closest point on the path within [s, s + window], never backwards.
  const double s_max = s_m_ + gains_.search_window_m;
  double best_d = (pointAt(s_m_) - p).norm(), best_s = s_m_;
  for (size_t i = 1; i < points_.size(); ++i) {
    if (cum_m_[i] < s_m_) continue;
    if (cum_m_[i - 1] > s_max) break;
    const Eigen::Vector2d a = points_[i - 1], ab = points_[i] - points_[i - 1];
    const double len2 = ab.squaredNorm();
    double f = len2 > 0 ? (p - a).dot(ab) / len2 : 0.0;
    f = std::clamp(f, 0.0, 1.0);
    double s = cum_m_[i - 1] + f * std::sqrt(len2);
    s = std::clamp(s, s_m_, s_max);
    const double d = (pointAt(s) - p).norm();
    if (d < best_d) best_d = d, best_s = s;
  }
  s_m_ = std::min(best_s, total_m_);
  out.cross_track_m = best_d;

  // Arrived: near the goal with (almost) the whole path covered, so that a path passing
  // near its own end point half-way does not finish early.
  const double remaining_m = total_m_ - s_m_;
  if (done_ || (out.distance_to_goal_m <= gains_.stop_radius_m &&
                remaining_m <= std::max(gains_.lookahead_m, 3 * gains_.stop_radius_m) + best_d)) {
    done_ = true;
    s_m_ = total_m_;
    out.progress = 1.0;
    out.done = true;
    return out;
  }
  out.progress = progress();

  // Pursuit point and the heading error toward it, in the robot frame.
  const Eigen::Vector2d target = remaining_m <= gains_.lookahead_m ? goal : pointAt(s_m_ + gains_.lookahead_m);
  const Eigen::Vector2d d = target - p;
  const double c = std::cos(pose.yaw), sn = std::sin(pose.yaw);
  const double dx = c * d.x() + sn * d.y(), dy = -sn * d.x() + c * d.y();
  const double dist = std::hypot(dx, dy);
  const double alpha = std::atan2(dy, dx);

  double v = 0, w = 0;
  if (dist < 1e-9) {
    v = w = 0;
  } else if (std::abs(alpha) > gains_.rotate_in_place_rad) {
    w = std::clamp(gains_.heading_gain * alpha, -gains_.max_turn_rate_radps, gains_.max_turn_rate_radps);
  } else {
    const double ramp = std::min(1.0, out.distance_to_goal_m / gains_.slowdown_radius_m);
    v = std::max(gains_.min_speed_mps, gains_.cruise_speed_mps * ramp) * std::max(0.0, std::cos(alpha));
    v = std::max(v, gains_.min_speed_mps);
    const double curvature = 2 * std::sin(alpha) / dist;
    w = v * curvature;
    if (std::abs(w) > gains_.max_turn_rate_radps) {
      // Keep the curvature, slow down.
      v *= gains_.max_turn_rate_radps / std::abs(w);
      w = std::copysign(gains_.max_turn_rate_radps, w);
    }
  }
  WheelSpeeds wheels = twistToWheels(v, w, gains_.wheel_base_m);
  const double peak = std::max(std::abs(wheels.left_mps), std::abs(wheels.right_mps));
  if (peak > gains_.max_wheel_speed_mps) {
    const double k = gains_.max_wheel_speed_mps / peak;
    wheels.left_mps *= k;
    wheels.right_mps *= k;
  }
  out.wheels = wheels;
  return out;
}

}  // namespace ddace::exec
