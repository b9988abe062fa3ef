#include "ddace/exec/clearance.h"

namespace ddace::exec {

ClearanceMeter::ClearanceMeter(std::vector<double> radii, double overlap_tolerance_m)
    : radii_(std::move(radii)),
      tolerance_m_(overlap_tolerance_m),
      pairs_(radii_.size() * radii_.size(), Pair::Unseen) {}

void ClearanceMeter::update(double time_s, const std::vector<Eigen::Vector2d>& positions) {
  const size_t n = std::min(radii_.size(), positions.size());
  for (size_t a = 0; a < n; ++a) {
    if (!(radii_[a] > 0) || !positions[a].allFinite()) continue;
    for (size_t b = a + 1; b < n; ++b) {
      if (!(radii_[b] > 0) || !positions[b].allFinite()) continue;
      Pair& state = pairs_[a * radii_.size() + b];
      const double gap = (positions[a] - positions[b]).norm() - radii_[a] - radii_[b];
      if (state == Pair::Unseen) {
        state = gap < 0 ? Pair::Loaded : Pair::Apart;
        if (state == Pair::Loaded) loaded_.emplace_back(static_cast<int>(a), static_cast<int>(b));
      }
      if (state == Pair::Loaded) continue;
      if (gap < closest_.clearance_m)
        closest_ = {gap, static_cast<int>(a), static_cast<int>(b), time_s, positions[a], positions[b]};
      if (state == Pair::Apart && gap < -tolerance_m_) {
        state = Pair::Touching;
        collisions_.push_back({time_s, static_cast<int>(a), static_cast<int>(b)});
      } else if (state == Pair::Touching && gap > tolerance_m_) {
        state = Pair::Apart;  // clearly separated (not noise): the next overlap is another collision
      }
    }
  }
}

}  // namespace ddace::exec
