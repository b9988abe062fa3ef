#include "ddace/exec/ride_path.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/angle.h"

namespace ddace::exec {

namespace {

/// A body may come no nearer than this below where it stands at the start (metres): the
/// noise of a pose, not an approach.
constexpr double kRideSlackM = 0.001;

/// The load's positions while the carrier drives `path`: from where it stands, round the
/// carrier's first point to ride_m ahead of its first heading, then ride_m ahead along
/// every leg.
std::vector<Eigen::Vector2d> loadAlong(const std::vector<Eigen::Vector2d>& path, const Eigen::Vector2d& load,
                                       double ride_m) {
  std::vector<Eigen::Vector2d> out{load};
  const Eigen::Vector2d rel = load - path.front();
  Eigen::Vector2d heading = Eigen::Vector2d::Zero();
  for (size_t k = 0; k + 1 < path.size(); ++k) {
    const Eigen::Vector2d leg = path[k + 1] - path[k];
    if (leg.norm() < 1e-9) continue;
    const Eigen::Vector2d h = leg.normalized();
    if (heading.isZero()) {
      const double from = std::atan2(rel.y(), rel.x()), turn = wrapAngle(std::atan2(h.y(), h.x()) - from);
      const int n = static_cast<int>(std::ceil(std::abs(turn) / kRideSwingStepRad));
      for (int s = 1; s <= n; ++s) {
        const double a = from + turn * s / n;
        out.push_back(path.front() + ride_m * Eigen::Vector2d(std::cos(a), std::sin(a)));
      }
    }
    heading = h;
    out.push_back(path[k + 1] + ride_m * heading);
  }
  return out;
}

/// Whether every point of `along` keeps `reach_m` from `centre`, or no nearer than its
/// first or its last point does (a body it starts or ends beside: the giver of a relay, the
/// robot a load is handed to).
bool keepsClear(const std::vector<Eigen::Vector2d>& along, const Eigen::Vector2d& centre, double reach_m) {
  const double floor_m =
      std::min({reach_m, (along.front() - centre).norm(), (along.back() - centre).norm()}) - kRideSlackM;
  return std::all_of(along.begin(), along.end(),
                     [&](const Eigen::Vector2d& p) { return (p - centre).norm() >= floor_m; });
}

}  // namespace

bool rideIsClear(const std::vector<Eigen::Vector2d>& path, const Eigen::Vector2d& load, double ride_m,
                 const std::vector<PushObstacle>& standing) {
  if (path.size() < 2) return false;
  const std::vector<Eigen::Vector2d> loads = loadAlong(path, load, ride_m);
  return std::all_of(standing.begin(), standing.end(), [&](const PushObstacle& o) {
    return keepsClear(path, o.centre, o.reach_m) && keepsClear(loads, o.centre, o.reach_m);
  });
}

bool drivesShownPath(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i, int load,
                     const std::vector<Eigen::Vector2d>& at, const std::vector<Eigen::Vector2d>& planned,
                     bool loads_ride) {
  if (!loads_ride) return false;
  const int carrier = step.at(i).entity;
  return rideIsClear(planned, at.at(static_cast<size_t>(load)), spec.contactDistance(carrier, load),
                     pushObstacles(spec, step, i, load, at));
}

}  // namespace ddace::exec
