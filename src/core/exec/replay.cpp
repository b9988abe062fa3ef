#include "ddace/exec/replay.h"

#include <complex>

#include "ddace/common/error.h"

namespace ddace::exec {

Decision replayDecision(const task::Demonstration& demo, const std::vector<task::Snapshot>& history) {
  Decision d;
  const size_t k = history.empty() ? 0 : history.size() - 1;
  if (k >= demo.steps.size()) {
    d.end = true;
    return d;
  }
  d.tokens = demo.steps[k].tokens;
  return d;
}

std::vector<Eigen::Vector2d> retargetPath(const std::vector<Eigen::Vector2d>& demo, const Eigen::Vector2d& start,
                                          const Eigen::Vector2d& goal) {
  if (demo.empty()) throw Error("cannot retarget an empty path");
  using C = std::complex<double>;
  const C a(demo.front().x(), demo.front().y()), b(demo.back().x(), demo.back().y());
  const C s(start.x(), start.y()), g(goal.x(), goal.y());
  // z -> s + (z - a) * (g - s) / (b - a): rotation and scale as one complex factor.
  const C factor = std::abs(b - a) > 1e-3 ? (g - s) / (b - a) : C(1, 0);
  std::vector<Eigen::Vector2d> out;
  out.reserve(demo.size());
  for (const auto& p : demo) {
    const C z = s + (C(p.x(), p.y()) - a) * factor;
    out.emplace_back(z.real(), z.imag());
  }
  if (std::abs(b - a) > 1e-3) out.back() = goal;
  return out;
}

DemonstrationPaths::DemonstrationPaths(const task::TaskSpec& spec, const std::vector<task::Demonstration>& demos)
    : spec_(spec) {
  for (const auto& demo : demos)
    for (const auto& seg : demo.segments)
      if (seg.token.isMotion()) {
        const std::string key = task::tokenKey(seg.token, spec_);
        if (!paths_.count(key)) paths_[key] = demo.segmentPath(seg);
      }
}

PlannedPath DemonstrationPaths::generate(const task::Token& token, const Eigen::Vector2d& start,
                                         const Eigen::Vector2d& goal) const {
  const std::string key = task::tokenKey(token, spec_);
  auto it = paths_.find(key);
  if (it == paths_.end()) throw Error("no demonstration has a segment of '" + key + "'");
  PlannedPath p;
  p.points = retargetPath(it->second, start, goal);
  p.stddev_m.assign(p.points.size(), 0.0);
  return p;
}

}  // namespace ddace::exec
