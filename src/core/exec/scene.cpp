#include "ddace/exec/scene.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/error.h"

namespace ddace::exec {

std::vector<Pose2D> startPoses(const task::Demonstration& demo, double min_motion_m) {
  if (demo.rows() == 0) throw Error(Diagnostic{demo.source, 0, 0, "demonstration has no rows"});
  const auto& first = demo.positions.front();
  std::vector<Pose2D> poses(first.size());
  for (size_t i = 0; i < first.size(); ++i) {
    poses[i].x = first[i].x();
    poses[i].y = first[i].y();
    for (size_t row = 1; row < demo.rows(); ++row) {
      const Eigen::Vector2d v = demo.positions[row][i] - first[i];
      if (v.norm() > min_motion_m) {
        poses[i].yaw = std::atan2(v.y(), v.x());
        break;
      }
    }
  }
  return poses;
}

std::vector<Pose2D> sceneStartPoses(const task::TaskSpec& spec, const std::vector<Pose2D>& base,
                                    const std::vector<NamedPose>& named, const std::string& missing_hint) {
  const size_t n = spec.entities.size();
  if (!base.empty() && base.size() != n)
    throw Error("a scene of " + std::to_string(base.size()) + " poses for task '" + spec.name + "' of " +
                std::to_string(n) + " entities");
  std::vector<Pose2D> poses = base.empty() ? std::vector<Pose2D>(n) : base;
  std::vector<bool> set(n, !base.empty());
  for (const NamedPose& p : named) {
    const int i = spec.entityIndex(p.name);
    if (i < 0) throw Error(p.where + ": no entity '" + p.name + "' in task '" + spec.name + "'");
    if (!std::isfinite(p.pose.x) || !std::isfinite(p.pose.y) || !std::isfinite(p.pose.yaw))
      throw Error(p.where + ": the pose of '" + p.name + "' is not finite");
    poses[i] = p.pose;
    set[i] = true;
  }
  for (size_t i = 0; i < n; ++i)
    if (!set[i]) throw Error("no start pose for entity '" + spec.entities[i].name + "': " + missing_hint);
  return poses;
}

CarriedObject::CarriedObject(std::vector<Eigen::Vector2d> path, const Eigen::Vector2d& from, double speed_mps)
    : path_(std::move(path)), speed_mps_(speed_mps) {
  if (path_.empty()) throw Error("an object's path is empty");
  if (!(speed_mps > 0) || !std::isfinite(speed_mps)) throw Error("an object's speed must be positive");
  path_.front() = from;
  cum_m_.assign(path_.size(), 0.0);
  for (size_t k = 1; k < path_.size(); ++k) cum_m_[k] = cum_m_[k - 1] + (path_[k] - path_[k - 1]).norm();
}

Eigen::Vector2d CarriedObject::position() const {
  if (path_.size() == 1 || arrived()) return path_.back();
  size_t k = 1;
  while (k + 1 < path_.size() && cum_m_[k] < s_m_) ++k;
  const double len = cum_m_[k] - cum_m_[k - 1];
  const double f = len > 0 ? (s_m_ - cum_m_[k - 1]) / len : 1.0;
  return path_[k - 1] + f * (path_[k] - path_[k - 1]);
}

Eigen::Vector2d CarriedObject::advance(double dt_s) {
  s_m_ = std::min(s_m_ + speed_mps_ * std::max(0.0, dt_s), cum_m_.back());
  return position();
}

}  // namespace ddace::exec
