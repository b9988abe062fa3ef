#include "ddace/exec/clearance.h"

#include <algorithm>
#include <string>

#include "ddace/common/error.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

bool PairContact::update(double gap, bool contact, bool allowed, double tolerance_m) {
  if (state_ == State::TouchingAllowed) {
    if (gap > tolerance_m) {
      state_ = State::Apart;  // parted: measured again
    } else if (!allowed && gap < -tolerance_m) {
      state_ = State::Collided;  // no longer allowed and pushing in: a robot shoving what it ended at
      return true;
    } else {
      return false;
    }
  }
  if (state_ == State::Collided) {
    if (!(gap > tolerance_m)) return false;
    state_ = State::Apart;  // clearly separated (not noise): the next contact is another collision
  }
  if (allowed) {
    if (gap <= tolerance_m) state_ = State::TouchingAllowed;
    return false;
  }
  if (!contact) return false;
  state_ = State::Collided;
  return true;
}

ClearanceMeter::ClearanceMeter(std::vector<double> radii, double overlap_tolerance_m)
    : radii_(std::move(radii)),
      tolerance_m_(overlap_tolerance_m),
      seen_(radii_.size() * radii_.size(), Seen::Unseen),
      contacts_(radii_.size() * radii_.size()) {}

void ClearanceMeter::update(double time_s, const std::vector<Eigen::Vector2d>& positions,
                            const AllowedContacts& allowed) {
  const size_t n = std::min(radii_.size(), positions.size());
  for (size_t a = 0; a < n; ++a) {
    if (!(radii_[a] > 0) || !positions[a].allFinite()) continue;
    for (size_t b = a + 1; b < n; ++b) {
      if (!(radii_[b] > 0) || !positions[b].allFinite()) continue;
      const size_t k = a * radii_.size() + b;
      const double gap = (positions[a] - positions[b]).norm() - radii_[a] - radii_[b];
      if (seen_[k] == Seen::Unseen) {
        seen_[k] = gap < -kPlacedOnM ? Seen::Loaded : Seen::Tracked;
        if (seen_[k] == Seen::Loaded) loaded_.emplace_back(static_cast<int>(a), static_cast<int>(b));
        if (seen_[k] == Seen::Tracked && gap < std::max(tolerance_m_, 0.0)) contacts_[k].touchingAtStart();
      }
      if (seen_[k] == Seen::Loaded) continue;
      const int ia = static_cast<int>(a), ib = static_cast<int>(b);
      const bool ok = allowed.allowed(ia, ib, positions[a], positions[b]);
      if (contacts_[k].update(gap, gap < -tolerance_m_, ok, tolerance_m_)) collisions_.push_back({time_s, ia, ib});
      if (contacts_[k].measured(ok) && gap < closest_.clearance_m)
        closest_ = {gap, ia, ib, time_s, positions[a], positions[b]};
    }
  }
}

}  // namespace ddace::exec
