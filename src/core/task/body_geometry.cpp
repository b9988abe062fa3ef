#include "ddace/task/body_geometry.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "ddace/common/error.h"

namespace ddace::task {

double stopTolerance(double noise_m) {
  return std::max(kArrivalToleranceM, 3 * noise_m);
}

double stopRadius(double arrival_radius, double tolerance) {
  return std::max(arrival_radius - tolerance, 0.5 * arrival_radius);
}

double stopRadiusAgainstBody(double stop_radius, double tolerance) {
  return std::min(stop_radius, tolerance);
}

bool arrived(const Eigen::Vector2d& position, const Eigen::Vector2d& end_point, double arrival_radius) {
  return (position - end_point).norm() <= arrival_radius;
}

double togetherDistance(const TaskSpec& spec, int a, int b) {
  return togetherDistance(spec.contactDistance(a, b), spec.arrival_radius);
}

double togetherDistance(double contact_m, double arrival_radius) {
  return std::max(2.0 * arrival_radius, contact_m + arrival_radius);
}

bool together(const TaskSpec& spec, int a, const Eigen::Vector2d& pa, int b, const Eigen::Vector2d& pb) {
  return (pa - pb).norm() <= togetherDistance(spec, a, b);
}

namespace {

bool finite(const Eigen::Vector2d& p) {
  return std::isfinite(p.x()) && std::isfinite(p.y());
}

void checkPositions(const TaskSpec& spec, const std::vector<Eigen::Vector2d>& positions) {
  if (positions.size() != spec.entities.size())
    throw Error("goal condition judged with " + std::to_string(positions.size()) + " positions for the " +
                std::to_string(spec.entities.size()) + " entities of task '" + spec.name + "'");
}

}  // namespace

double reachableDistance(const TaskSpec& spec, int entity, int at, const std::vector<Eigen::Vector2d>& positions) {
  checkPositions(spec, positions);
  const int n = static_cast<int>(positions.size());
  if (entity < 0 || entity >= n || at < 0 || at >= n)
    throw Error("reachable distance of an entity outside the " + std::to_string(n) + " of task '" + spec.name + "'");
  const Eigen::Vector2d a = positions[static_cast<size_t>(at)], e = positions[static_cast<size_t>(entity)];
  const double length = (e - a).norm();
  if (!spec.footprint(entity).obstacle || !finite(a) || !finite(e) || length < 1e-12) return 0;
  const Eigen::Vector2d u = (e - a) / length;
  // Where along the ray the body of `entity` would overlap each other obstacle: (s1, s2).
  std::vector<std::pair<double, double>> blocked;
  for (int b = 0; b < n; ++b) {
    const Eigen::Vector2d p = positions[static_cast<size_t>(b)];
    const double contact = spec.contactDistance(entity, b);
    if (b == entity || b == at || !(contact > 0) || !finite(p)) continue;
    const Eigen::Vector2d w = a - p;
    const double half = w.dot(u), disc = half * half - (w.squaredNorm() - contact * contact);
    if (disc <= 0) continue;
    const double root = std::sqrt(disc);
    if (-half + root > 0) blocked.emplace_back(-half - root, -half + root);
  }
  std::sort(blocked.begin(), blocked.end());
  constexpr double kSlack = 1e-12;  // floating point, not geometry
  double s = 0;
  for (const auto& [s1, s2] : blocked)  // by where they begin: s is free once the next begins beyond it
    if (s1 < s - kSlack) s = std::max(s, s2);
  return s;
}

bool goalConditionMet(const TaskSpec& spec, const GoalCondition& condition,
                      const std::vector<Eigen::Vector2d>& positions) {
  checkPositions(spec, positions);
  const int e = spec.entityIndex(condition.entity), a = spec.entityIndex(condition.at);
  if (e < 0 || a < 0 || !finite(positions[static_cast<size_t>(e)]) || !finite(positions[static_cast<size_t>(a)]))
    return false;
  const double d = (positions[static_cast<size_t>(e)] - positions[static_cast<size_t>(a)]).norm();
  return d - reachableDistance(spec, e, a, positions) <= condition.tolerance;
}

}  // namespace ddace::task
