#include "ddace/exec/clearance.h"

#include <algorithm>
#include <string>

#include "ddace/common/error.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

namespace {
std::pair<int, int> ordered(int a, int b) {
  return {std::min(a, b), std::max(a, b)};
}
}  // namespace

AllowedContacts::AllowedContacts(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                                 const std::vector<Eigen::Vector2d>& ends, const std::vector<bool>& moves,
                                 const std::vector<double>& radii, double margin_m)
    : ends_(ends), moves_(moves), radii_(radii), margin_m_(margin_m) {
  const auto n = static_cast<int>(ends.size());
  if (moves.size() != ends.size() || radii.size() != ends.size())
    throw Error("allowed contacts: " + std::to_string(ends.size()) + " end positions, " + std::to_string(moves.size()) +
                " motion flags and " + std::to_string(radii.size()) + " radii");
  for (size_t i = 0; i < tokens.size(); ++i) {
    const task::Token& t = tokens[i];
    if (!t.isMotion()) continue;
    if (t.entity < 0 || t.entity >= n || t.target >= n)
      throw Error("allowed contacts: a token names an entity outside the " + std::to_string(n) + " given");
    if (t.target >= 0) exempt_.insert(ordered(t.entity, t.target));
    const int load = task::carriedLoad(spec, tokens, i);
    if (load >= 0) exempt_.insert(ordered(t.entity, tokens[static_cast<size_t>(load)].entity));
  }
  for (int a = 0; a < n; ++a) {
    if (!moves_[a] || !(radii_[a] > 0)) continue;
    for (int b = 0; b < n; ++b)
      if (b != a && radii_[b] > 0 && endsAgainst(ends_[a], radii_[a], ends_[b], radii_[b], margin_m_))
        ends_against_.insert(ordered(a, b));
  }
}

bool AllowedContacts::endsAgainstNow(int a, int b, const Eigen::Vector2d& pb) const {
  const auto n = static_cast<int>(ends_.size());
  return a >= 0 && a < n && b >= 0 && b < n && moves_[a] && ends_against_.count(ordered(a, b)) &&
         endsAgainst(ends_[a], radii_[a], pb, radii_[b], margin_m_);
}

bool AllowedContacts::allowed(int a, int b, const Eigen::Vector2d& pa, const Eigen::Vector2d& pb) const {
  return exempt_.count(ordered(a, b)) || endsAgainstNow(a, b, pb) || endsAgainstNow(b, a, pa);
}

ClearanceMeter::ClearanceMeter(std::vector<double> radii, double overlap_tolerance_m)
    : radii_(std::move(radii)),
      tolerance_m_(overlap_tolerance_m),
      pairs_(radii_.size() * radii_.size(), Pair::Unseen) {}

void ClearanceMeter::update(double time_s, const std::vector<Eigen::Vector2d>& positions,
                            const AllowedContacts& allowed) {
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
      if (state == Pair::TouchingAllowed) {
        if (gap <= tolerance_m_) continue;
        state = Pair::Apart;  // parted: measured again
      }
      if (allowed.allowed(static_cast<int>(a), static_cast<int>(b), positions[a], positions[b])) {
        if (state == Pair::Apart && gap <= tolerance_m_) state = Pair::TouchingAllowed;
        continue;
      }
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
