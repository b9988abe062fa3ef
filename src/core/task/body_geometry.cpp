#include "ddace/task/body_geometry.h"

#include <algorithm>

namespace ddace::task {

double stopTolerance(double noise_m) {
  return std::max(kArrivalToleranceM, 3 * noise_m);
}

double stopRadius(double arrival_radius, double tolerance) {
  return std::max(arrival_radius - tolerance, 0.5 * arrival_radius);
}

double stopRadiusToward(double stop_radius, double tolerance, double together_m, double end_to_target_m) {
  return std::min(stop_radius, std::max(tolerance, together_m - end_to_target_m - tolerance));
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

}  // namespace ddace::task
