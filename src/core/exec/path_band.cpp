#include "ddace/exec/path_band.h"

namespace ddace::exec {

void sigmaBandEdges(const PlannedPath& path, double k_sigma, std::vector<Eigen::Vector2d>& left,
                    std::vector<Eigen::Vector2d>& right) {
  left.clear();
  right.clear();
  const auto& pts = path.points;
  if (pts.size() < 2) return;
  for (size_t k = 0; k < pts.size(); ++k) {
    const Eigen::Vector2d d = (k + 1 < pts.size() ? pts[k + 1] - pts[k] : pts[k] - pts[k - 1]);
    const Eigen::Vector2d normal = d.norm() > 0 ? Eigen::Vector2d(-d.y(), d.x()) / d.norm() : Eigen::Vector2d(0, 0);
    const double sd = k < path.stddev_m.size() ? path.stddev_m[k] : 0.0;
    left.push_back(pts[k] + k_sigma * sd * normal);
    right.push_back(pts[k] - k_sigma * sd * normal);
  }
}

std::vector<Eigen::Vector2d> sigmaBandTriangles(const PlannedPath& path, double k_sigma) {
  std::vector<Eigen::Vector2d> left, right, tri;
  sigmaBandEdges(path, k_sigma, left, right);
  for (size_t k = 0; k + 1 < left.size(); ++k)
    for (const auto& p : {left[k], right[k], left[k + 1], left[k + 1], right[k], right[k + 1]}) tri.push_back(p);
  return tri;
}

}  // namespace ddace::exec
