#include "ddace/gp/canonical.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "ddace/common/error.h"

namespace ddace::gp {

CanonicalFrame::CanonicalFrame(const Eigen::Vector2d& start, const Eigen::Vector2d& end) : origin_(start) {
  const Eigen::Vector2d d = end - start;
  scale_ = d.norm();
  if (!std::isfinite(scale_) || scale_ < kMinMotionLength) {
    std::ostringstream msg;
    msg << "no canonical frame for a motion from (" << start.x() << ", " << start.y() << ") to (" << end.x() << ", "
        << end.y() << "): start and end coincide";
    throw Error(msg.str());
  }
  angle_ = std::atan2(d.y(), d.x());
  rotation_ << std::cos(angle_), -std::sin(angle_), std::sin(angle_), std::cos(angle_);
}

Eigen::Vector2d CanonicalFrame::toCanonical(const Eigen::Vector2d& p) const {
  return rotation_.transpose() * (p - origin_) / scale_;
}

Eigen::Vector2d CanonicalFrame::fromCanonical(const Eigen::Vector2d& c) const {
  return origin_ + scale_ * (rotation_ * c);
}

std::vector<Eigen::Vector2d> CanonicalFrame::toCanonical(const std::vector<Eigen::Vector2d>& path) const {
  std::vector<Eigen::Vector2d> out;
  out.reserve(path.size());
  for (const auto& p : path) out.push_back(toCanonical(p));
  return out;
}

std::vector<Eigen::Vector2d> CanonicalFrame::fromCanonical(const std::vector<Eigen::Vector2d>& path) const {
  std::vector<Eigen::Vector2d> out;
  out.reserve(path.size());
  for (const auto& c : path) out.push_back(fromCanonical(c));
  return out;
}

std::vector<double> progress(const std::vector<Eigen::Vector2d>& path) {
  std::vector<double> s(path.size(), 0.0);
  for (size_t i = 1; i < path.size(); ++i) s[i] = s[i - 1] + (path[i] - path[i - 1]).norm();
  const double total = s.empty() ? 0.0 : s.back();
  if (total > 0)
    for (double& v : s) v /= total;
  return s;
}

std::vector<Eigen::Vector2d> resampleByProgress(const std::vector<Eigen::Vector2d>& path, int n) {
  if (path.empty()) throw Error("cannot resample an empty path");
  if (n < 2) throw Error("resampling needs at least 2 points, got " + std::to_string(n));
  for (const auto& p : path)
    if (!p.allFinite()) throw Error("cannot resample a path with a non-finite point");
  const std::vector<double> s = progress(path);
  std::vector<Eigen::Vector2d> out(n, path.front());
  if (s.back() <= 0) return out;
  size_t seg = 0;  // s[seg] <= target <= s[seg + 1]
  for (int k = 1; k < n - 1; ++k) {
    const double target = static_cast<double>(k) / (n - 1);
    while (seg + 2 < s.size() && s[seg + 1] < target) ++seg;
    const double span = s[seg + 1] - s[seg];
    const double f = span > 0 ? std::clamp((target - s[seg]) / span, 0.0, 1.0) : 0.0;
    out[k] = path[seg] + f * (path[seg + 1] - path[seg]);
  }
  out.back() = path.back();
  return out;
}

}  // namespace ddace::gp
