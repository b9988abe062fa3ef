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
                                 const std::vector<Eigen::Vector2d>& starts, const std::vector<Eigen::Vector2d>& ends,
                                 const std::vector<bool>& moves, const std::vector<double>& radii, double margin_m)
    : ends_(ends), moves_(moves), radii_(radii), margin_m_(margin_m) {
  const auto n = static_cast<int>(ends.size());
  if (moves.size() != ends.size() || radii.size() != ends.size() || starts.size() != ends.size())
    throw Error("allowed contacts: " + std::to_string(starts.size()) + " start positions, " +
                std::to_string(ends.size()) + " end positions, " + std::to_string(moves.size()) + " motion flags and " +
                std::to_string(radii.size()) + " radii");
  for (size_t i = 0; i < tokens.size(); ++i) {
    const task::Token& t = tokens[i];
    if (!t.isMotion()) continue;
    if (t.entity < 0 || t.entity >= n || t.target >= n)
      throw Error("allowed contacts: a token names an entity outside the " + std::to_string(n) + " given");
    if (t.target >= 0) exempt_.insert(ordered(t.entity, t.target));
    const int load = task::ridingLoad(spec, tokens, i, starts);  // one passed from afar keeps apart
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

StepContacts::StepContacts(task::TaskSpec spec, std::vector<double> radii, double margin_m)
    : spec_(std::move(spec)), radii_(std::move(radii)), margin_m_(margin_m) {}

void StepContacts::beginStep(int step) {
  if (step != step_) ends_.clear(), allowed_ = {}, step_ = step;  // no exemption of the last step stays
}

void StepContacts::note(int step, int entity, const task::Token& token, const Eigen::Vector2d& end,
                        const std::vector<Eigen::Vector2d>& at) {
  beginStep(step);
  const auto n = static_cast<int>(spec_.entities.size());
  const auto name = [&](int i) { return i >= 0 && i < n ? spec_.entities[i].name : "entity " + std::to_string(i); };
  if (token.entity != entity)
    throw Error("the segment of " + name(entity) + " carries a token of " + name(token.entity) +
                ": not counted for the allowed contacts");
  if (entity < 0 || entity >= static_cast<int>(at.size()))
    throw Error("the segment of " + name(entity) +
                " names no entity with a pose: not counted for the allowed contacts");
  // Kept only once the step's contacts are worked out with it: a bad segment leaves the
  // step's others as they were.
  auto step_ends = ends_;
  step_ends[entity] = {token, end};
  std::vector<task::Token> tokens;
  std::vector<Eigen::Vector2d> ends = at;
  std::vector<bool> moves(at.size(), false);
  for (const auto& [e, te] : step_ends) {
    tokens.push_back(te.first);
    ends[e] = te.second;
    moves[e] = true;
  }
  try {
    allowed_ = AllowedContacts(spec_, tokens, at, ends, moves, radii_, margin_m_);
  } catch (const Error&) {
    allowed_ = {};  // every contact counts
    throw;
  }
  ends_ = std::move(step_ends);
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
        seen_[k] = gap < 0 ? Seen::Loaded : Seen::Tracked;
        if (seen_[k] == Seen::Loaded) loaded_.emplace_back(static_cast<int>(a), static_cast<int>(b));
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
