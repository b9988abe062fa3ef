#include "ddace/exec/push_path.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ddace/common/angle.h"
#include "ddace/common/error.h"
#include "ddace/exec/path_follower.h"

#include "ddace/task/end_point.h"

namespace ddace::exec {

namespace {

Eigen::Vector2d onCircle(const Eigen::Vector2d& centre, double radius, double angle) {
  return centre + radius * Eigen::Vector2d(std::cos(angle), std::sin(angle));
}

/// Where a load at `load` stands on its route (exec::loadRoute): the nearest point of the
/// route, the last leg taken as a ray beyond its end.
struct OnRoute {
  size_t leg = 1;      ///< the leg (route[leg - 1] to route[leg]) nearest the load
  double along_m = 0;  ///< how far along that leg (beyond its length on the last: past the end)
};

OnRoute onRoute(const std::vector<Eigen::Vector2d>& route, const Eigen::Vector2d& load) {
  OnRoute best;
  double nearest = std::numeric_limits<double>::infinity();
  for (size_t k = 1; k < route.size(); ++k) {
    const Eigen::Vector2d leg = route[k] - route[k - 1];
    const double length = leg.norm();
    double along = length > 0 ? (load - route[k - 1]).dot(leg) / length : 0.0;
    along = std::max(0.0, k + 1 == route.size() ? along : std::min(along, length));
    const Eigen::Vector2d p = route[k - 1] + (length > 0 ? along / length : 0.0) * leg;
    if ((p - load).norm() <= nearest) nearest = (p - load).norm(), best = {k, along};
  }
  return best;
}

/// The point `ahead_m` of route beyond `at` (past the route's end: on along its last leg).
Eigen::Vector2d routeAhead(const std::vector<Eigen::Vector2d>& route, OnRoute at, double ahead_m) {
  double left = at.along_m + ahead_m;
  for (size_t k = at.leg; k < route.size(); ++k) {
    const Eigen::Vector2d leg = route[k] - route[k - 1];
    if (k + 1 == route.size() || left <= leg.norm()) return route[k - 1] + left * leg.normalized();
    left -= leg.norm();
  }
  return route.back();
}

bool pastEnd(const std::vector<Eigen::Vector2d>& route, const OnRoute& at) {
  return at.leg + 1 == route.size() && at.along_m >= (route.back() - route[route.size() - 2]).norm();
}

double distanceToSegment(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

/// Where a load standing at `at` on its route heads (pushWheels): the farthest point of the
/// route within kPushLookaheadM ahead whose straight way from there keeps within
/// kPushNearPassM of the route (the least room a route leaves beyond a body's reach), so
/// a push cuts a bend by no more than that; at a sharp bend the push breaks and is planned
/// again behind the next leg.
Eigen::Vector2d pushAim(const std::vector<Eigen::Vector2d>& route, const OnRoute& at) {
  const Eigen::Vector2d from = routeAhead(route, at, 0);
  const Eigen::Vector2d farthest = routeAhead(route, at, kPushLookaheadM);
  std::vector<Eigen::Vector2d> passed;  // the route's corners between `from` and a candidate
  double arc = (route[at.leg] - from).norm();
  for (size_t k = at.leg; k + 1 < route.size() && arc < kPushLookaheadM; ++k) {
    for (const Eigen::Vector2d& c : passed)
      if (distanceToSegment(c, from, route[k]) > kPushNearPassM) return passed.back();
    passed.push_back(route[k]);
    arc += (route[k + 1] - route[k]).norm();
  }
  for (const Eigen::Vector2d& c : passed)
    if (distanceToSegment(c, from, farthest) > kPushNearPassM) return passed.back();
  return farthest;
}

/// How far the contact normal `contact` (carrier to load) turns from where the load should
/// head (pushAim).
double contactDrift(const Eigen::Vector2d& contact, const Eigen::Vector2d& load,
                    const std::vector<Eigen::Vector2d>& route, const OnRoute& at) {
  const Eigen::Vector2d aim = pushAim(route, at) - load;
  return wrapAngle(std::atan2(contact.y(), contact.x()) - std::atan2(aim.y(), aim.x()));
}

/// `points` without consecutive repeats.
std::vector<Eigen::Vector2d> distinct(const std::vector<Eigen::Vector2d>& points) {
  std::vector<Eigen::Vector2d> out;
  for (const Eigen::Vector2d& p : points)
    if (out.empty() || (p - out.back()).norm() > 1e-9) out.push_back(p);
  return out;
}

/// How far `path` keeps clear of the reach of every body of `standing` (< 0: into one).
double clearance(const std::vector<Eigen::Vector2d>& path, const std::vector<PushObstacle>& standing) {
  double out = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < path.size(); ++k)
    for (const PushObstacle& o : standing)
      out = std::min(out, distanceToSegment(o.centre, path[k > 0 ? k - 1 : 0], path[k]) - o.reach_m);
  return out;
}

bool keepsClear(const std::vector<Eigen::Vector2d>& path, const std::vector<PushObstacle>& standing) {
  constexpr double kSlack = 1e-9;  // floating point, not geometry
  return clearance(path, standing) >= -kSlack;
}

bool keepsClear(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::vector<PushObstacle>& standing) {
  return keepsClear(std::vector<Eigen::Vector2d>{a, b}, standing);
}

/// `standing` as passed on a way from `a` to `b`: a body within its reach of either end is
/// passed kPushNearPassM beyond contact, and never nearer than it is there.
std::vector<PushObstacle> passable(std::vector<PushObstacle> standing, const Eigen::Vector2d& a,
                                   const Eigen::Vector2d& b) {
  for (PushObstacle& o : standing) {
    const double near = std::min((a - o.centre).norm(), (b - o.centre).norm());
    if (near < o.reach_m) o.reach_m = std::min(near, o.reach_m - kPushPassM + kPushNearPassM);
  }
  return standing;
}

/// Corners of the ways round `standing`: kCornersPerBody about each, kPushPassM beyond its
/// reach, where no other body's reach is.
std::vector<Eigen::Vector2d> corners(const std::vector<PushObstacle>& standing) {
  constexpr int kCornersPerBody = 12;
  std::vector<Eigen::Vector2d> out;
  for (const PushObstacle& o : standing)
    for (int k = 0; k < kCornersPerBody; ++k) {
      // Beyond the reach by the polygon's sag, so that the way between two corners keeps it.
      const double r = (o.reach_m + kPushPassM) / std::cos(M_PI / kCornersPerBody);
      const Eigen::Vector2d p = onCircle(o.centre, r, 2 * M_PI * k / kCornersPerBody);
      if (keepsClear(p, p, standing)) out.push_back(p);
    }
  return out;
}

/// Where a carrier behind the load at the start of `route` heads it first (pushAim), a
/// unit vector.
Eigen::Vector2d firstHeading(const std::vector<Eigen::Vector2d>& route) {
  const Eigen::Vector2d aim = pushAim(route, onRoute(route, route.front())) - route.front();
  return aim.norm() > 1e-9 ? aim.normalized() : Eigen::Vector2d(route[1] - route[0]).normalized();
}

double length(const std::vector<Eigen::Vector2d>& path) {
  double out = 0;
  for (size_t k = 1; k < path.size(); ++k) out += (path[k] - path[k - 1]).norm();
  return out;
}

/// Whether a carrier can line up behind a load at `load` to push it along `heading`: its
/// run-up, from contact out to kPushClearanceM beyond it, keeps every body of `standing`
/// `within_m` short of its reach.
bool runUpFree(const Eigen::Vector2d& load, const Eigen::Vector2d& heading, double contact_m,
               std::vector<PushObstacle> standing, double within_m = 0) {
  for (PushObstacle& o : standing) o.reach_m -= within_m;
  return keepsClear(load - contact_m * heading, load - (contact_m + kPushClearanceM) * heading, standing);
}

/// Whether the run-up of a push along `route` is taken by a standing body: the safety
/// filter would hold the carrier off it (kPushNearPassM, its margin) before it is behind
/// the load.
bool runUpTaken(const std::vector<Eigen::Vector2d>& route, double contact_m,
                const std::vector<PushObstacle>& standing) {
  return !runUpFree(route.front(), firstHeading(route), contact_m, standing, kPushPassM - kPushNearPassM);
}

/// Whether a carrier can go round a load at `load` at kPushClearanceM beyond their contact
/// (where a push planned again goes round it) keeping every body of `standing` at its reach.
bool roundFree(const Eigen::Vector2d& load, double contact_m, const std::vector<PushObstacle>& standing) {
  std::vector<Eigen::Vector2d> ring;
  for (double a = 0; a < 2 * M_PI + kPushArcStepRad; a += kPushArcStepRad)
    ring.push_back(onCircle(load, contact_m + kPushClearanceM, a));
  return keepsClear(ring, standing);
}

/// Whether the load at `load`, pushed straight `normal` (a unit vector: the carrier's
/// contact normal) for kPushClearanceM, runs into the reach of a body of `standing`, and
/// kPushNearPassM deeper than pushed as far along `heading` (where it should head: a
/// push along it that bends round a body soon after leaves the same body near): a body
/// the load stands within the reach of is passed kPushNearPassM beyond contact, no nearer
/// than it is.
bool normalRunsIntoBody(const Eigen::Vector2d& load, const Eigen::Vector2d& normal, const Eigen::Vector2d& heading,
                        const std::vector<PushObstacle>& standing) {
  const std::vector<PushObstacle> bodies = passable(standing, load, load);
  const auto pushed = [&](const Eigen::Vector2d& way) {
    return clearance(std::vector<Eigen::Vector2d>{load, load + kPushClearanceM * way}, bodies);
  };
  const double along_normal = pushed(normal);
  return along_normal < 0 && along_normal < pushed(heading) - kPushNearPassM;
}

/// The route of a load at `load` led out along `way` (a unit vector) before it is pushed on
/// to `load_end`: out as far as the carrier then goes round the load freely (a push planned
/// again at the turn), the run-up of the rest (pushRoute from the turn) free, then on;
/// nothing when the load would run into a body first or no turn is free within kMaxLeadOutM.
std::optional<std::vector<Eigen::Vector2d>> ledOutAlong(const Eigen::Vector2d& load, const Eigen::Vector2d& way,
                                                        const Eigen::Vector2d& load_end, double contact_m,
                                                        const std::vector<PushObstacle>& standing) {
  constexpr double kLeadOutStepM = 0.01, kMaxLeadOutM = 0.3;
  for (double out_m = kLeadOutStepM; out_m <= kMaxLeadOutM; out_m += kLeadOutStepM) {
    const Eigen::Vector2d turn = load + out_m * way;
    if (!keepsClear(load, turn, passable(standing, load, turn))) return std::nullopt;  // into a body
    if (!roundFree(turn, contact_m, standing)) continue;
    const std::vector<Eigen::Vector2d> on = distinct(pushRoute(turn, load_end, standing));
    if (on.size() < 2 || !runUpFree(turn, firstHeading(on), contact_m, standing)) return std::nullopt;
    std::vector<Eigen::Vector2d> route{load};
    route.insert(route.end(), on.begin(), on.end());
    return route;
  }
  return std::nullopt;
}

/// A route for a load whose run-up is taken by a body standing behind it (a relay's giver
/// that handed it on, the box between the two robots): first out from beside that body
/// along one of kLeadOutWays whose run-up keeps every standing body at its reach
/// (ledOutAlong). Of those, the one whose carrier's whole path (pushPathAlong from `from`)
/// is shortest; nothing when no way is free.
std::optional<std::vector<Eigen::Vector2d>> leadOutRoute(const Eigen::Vector2d& from, const Eigen::Vector2d& load,
                                                         const Eigen::Vector2d& load_end, double contact_m,
                                                         const std::vector<PushObstacle>& standing) {
  constexpr int kLeadOutWays = 24;
  std::optional<std::vector<Eigen::Vector2d>> best;
  double shortest = std::numeric_limits<double>::infinity();
  for (int k = 0; k < kLeadOutWays; ++k) {
    const Eigen::Vector2d way(std::cos(2 * M_PI * k / kLeadOutWays), std::sin(2 * M_PI * k / kLeadOutWays));
    if (!runUpFree(load, way, contact_m, standing)) continue;
    const auto route = ledOutAlong(load, way, load_end, contact_m, standing);
    if (!route) continue;
    constexpr int kMeasuredPoints = 200;  // the carrier's path drawn to measure its length
    const double driven = length(pushPathAlong(from, *route, contact_m, kMeasuredPoints, standing));
    if (driven < shortest) shortest = driven, best = route;
  }
  return best;
}

/// A carrier's way from `from` to the circle of `radius` round the load at `load`, reached
/// at bearing `arrive`, then round it by `turn` radians.
std::vector<Eigen::Vector2d> roundFrom(const Eigen::Vector2d& from, const Eigen::Vector2d& load, double radius,
                                       double arrive, double turn) {
  std::vector<Eigen::Vector2d> arc{from};
  const int steps = static_cast<int>(std::ceil(std::abs(turn) / kPushArcStepRad));
  for (int k = 0; k <= steps; ++k) arc.push_back(onCircle(load, radius, arrive + turn * k / std::max(steps, 1)));
  return arc;
}

/// The way of a carrier at `from` round its load at `load` on the circle of `radius` to the
/// run-up at bearing `behind`: out to the circle along the ray from the load (or in, from
/// afar), round it the shorter way, else the longer, whichever is free of `standing`
/// (passed no nearer than the carrier stands, passable); nothing when neither is.
std::optional<std::vector<Eigen::Vector2d>> freeWayRound(const Eigen::Vector2d& from, const Eigen::Vector2d& load,
                                                         double radius, double behind,
                                                         const std::vector<PushObstacle>& standing) {
  const double bearing = std::atan2(from.y() - load.y(), from.x() - load.x());
  const double shorter = wrapAngle(behind - bearing);
  const std::vector<PushObstacle> bodies = passable(standing, from, onCircle(load, radius, behind));
  for (const double turn : {shorter, shorter - std::copysign(2 * M_PI, shorter)}) {
    std::vector<Eigen::Vector2d> way = roundFrom(from, load, radius, bearing, turn);
    if (keepsClear(way, bodies)) return way;
  }
  return std::nullopt;
}

/// The run-up's bearing from the load at the start of `route` (behind where the push first
/// heads it).
double runUpBearing(const std::vector<Eigen::Vector2d>& route) {
  const Eigen::Vector2d w = firstHeading(route);
  return std::atan2(-w.y(), -w.x());
}

/// A route for a load whose carrier at `from` stands at it boxed in: a body stands within
/// its reach there, it may not push the load along `route` from there and has no free way
/// round it to the run-up (freeWayRound), but it may push it straight on along their
/// contact normal: out that way first (ledOutAlong), then round it and on. Nothing where
/// the carrier is not so boxed in, or no way out is.
std::optional<std::vector<Eigen::Vector2d>> pushedOutRoute(const Eigen::Vector2d& from,
                                                           const std::vector<Eigen::Vector2d>& route, double contact_m,
                                                           const std::vector<PushObstacle>& standing) {
  const Eigen::Vector2d& load = route.front();
  const Eigen::Vector2d normal = load - from;
  const bool beside_body = std::any_of(standing.begin(), standing.end(),
                                       [&](const PushObstacle& o) { return (o.centre - from).norm() < o.reach_m; });
  if (!beside_body || normal.norm() < 1e-9 || normal.norm() > contact_m + kPushClearanceM / 3 ||
      pushMayStartHere(from, load, route, contact_m, standing) ||
      freeWayRound(from, load, contact_m + kPushClearanceM, runUpBearing(route), standing))
    return std::nullopt;
  const auto out = ledOutAlong(load, normal.normalized(), route.back(), contact_m, standing);
  if (!out || !pushMayStartHere(from, load, *out, contact_m, standing)) return std::nullopt;
  return out;
}

}  // namespace

std::vector<Eigen::Vector2d> pushRoute(const Eigen::Vector2d& load, const Eigen::Vector2d& load_end,
                                       const std::vector<PushObstacle>& standing) {
  const std::vector<PushObstacle> bodies = passable(standing, load, load_end);
  if (keepsClear(load, load_end, bodies)) return {load, load_end};
  // The shortest way through the corners (Dijkstra on the free straight legs between them).
  // A body the load stands or ends beside is passed nearer only on the leg leaving it or
  // arriving at it: a leg between two corners keeps every body at its reach, or the route
  // would run along beside that body the whole way round it.
  std::vector<Eigen::Vector2d> nodes{load, load_end};
  for (const Eigen::Vector2d& c : corners(bodies)) nodes.push_back(c);
  const std::vector<PushObstacle> leaving = passable(standing, load, load),
                                  arriving = passable(standing, load_end, load_end);
  const auto legBodies = [&](size_t u, size_t v) -> const std::vector<PushObstacle>& {
    const bool from_start = u == 0 || v == 0, to_end = u == 1 || v == 1;
    return from_start && to_end ? bodies : from_start ? leaving : to_end ? arriving : standing;
  };
  const size_t n = nodes.size();
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  std::vector<int> previous(n, -1);
  std::vector<bool> done(n, false);
  dist[0] = 0;
  for (size_t round = 0; round < n; ++round) {
    size_t u = n;
    for (size_t k = 0; k < n; ++k)
      if (!done[k] && std::isfinite(dist[k]) && (u == n || dist[k] < dist[u])) u = k;
    if (u == n || u == 1) break;
    done[u] = true;
    for (size_t v = 0; v < n; ++v) {
      const double d = dist[u] + (nodes[v] - nodes[u]).norm();
      if (done[v] || d >= dist[v] || !keepsClear(nodes[u], nodes[v], legBodies(u, v))) continue;
      dist[v] = d;
      previous[v] = static_cast<int>(u);
    }
  }
  if (previous[1] < 0) return {load, load_end};  // no way round: straight, as without bodies
  std::vector<Eigen::Vector2d> route;
  for (int k = 1; k >= 0; k = previous[static_cast<size_t>(k)]) route.push_back(nodes[static_cast<size_t>(k)]);
  std::reverse(route.begin(), route.end());
  return route;
}

std::vector<Eigen::Vector2d> pushPath(const Eigen::Vector2d& from, const Eigen::Vector2d& load,
                                      const Eigen::Vector2d& load_end, double contact_m,
                                      const Eigen::Vector2d& fallback_end, int points,
                                      const std::vector<PushObstacle>& standing, bool push_from_behind) {
  if ((load_end - load).norm() < task::kMinApproachM)
    return resampleByArcLength(PlannedPath{{from, fallback_end}, {}}, std::max(points, 2)).points;
  return pushPathAlong(from, withRunUp(from, pushRoute(load, load_end, standing), contact_m, standing), contact_m,
                       points, standing, push_from_behind);
}

std::vector<Eigen::Vector2d> withRunUp(const Eigen::Vector2d& from, std::vector<Eigen::Vector2d> load_route,
                                       double contact_m, const std::vector<PushObstacle>& standing) {
  load_route = distinct(load_route);
  if (load_route.size() < 2) return load_route;
  if (auto out = pushedOutRoute(from, load_route, contact_m, standing)) return *out;
  if (!runUpTaken(load_route, contact_m, standing)) return load_route;
  return leadOutRoute(from, load_route.front(), load_route.back(), contact_m, standing).value_or(load_route);
}

std::vector<Eigen::Vector2d> pushPathAlong(const Eigen::Vector2d& from, const std::vector<Eigen::Vector2d>& load_route,
                                           double contact_m, int points, const std::vector<PushObstacle>& standing,
                                           bool push_from_behind) {
  const std::vector<Eigen::Vector2d> route = distinct(load_route);
  if (route.size() < 2) throw Error("a push route needs two distinct points");
  const Eigen::Vector2d load = route.front();
  // The run-up lies behind the load from where the push first heads it (pushAim).
  const double radius = contact_m + kPushClearanceM;
  const double behind = runUpBearing(route);
  std::vector<Eigen::Vector2d> out{from};
  const Eigen::Vector2d rel = from - load;
  if (push_from_behind && pushMayStartHere(from, load, route, contact_m, standing)) {
    // Already behind it, at it: the push starts here, through where the load stands (the
    // load's route is the carrier's path beyond it, loadRoute).
    out.push_back(load);
  } else if (rel.norm() > 1e-9) {
    // Out to the circle (or in, from afar), round it to the run-up: the shorter way unless
    // only the longer one is free of the standing bodies.
    const double bearing = std::atan2(rel.y(), rel.x());
    out = freeWayRound(from, load, radius, behind, standing)
              .value_or(roundFrom(from, load, radius, bearing, wrapAngle(behind - bearing)));
  } else {
    out.push_back(onCircle(load, radius, behind));
  }
  // Along the route, the load in front: the carrier ends behind the load's end on the last leg.
  for (size_t k = 1; k + 1 < route.size(); ++k) out.push_back(route[k]);
  const Eigen::Vector2d last = (route.back() - route[route.size() - 2]).normalized();
  out.push_back(route.back() - contact_m * last);
  return resampleByArcLength(PlannedPath{std::move(out), {}}, std::max(points, 2)).points;
}

std::vector<Eigen::Vector2d> loadRoute(const std::vector<Eigen::Vector2d>& carrier_path,
                                       const Eigen::Vector2d& planned_load, const Eigen::Vector2d& load,
                                       const Eigen::Vector2d& load_end) {
  size_t nearest = 0;
  for (size_t k = 0; k < carrier_path.size(); ++k)
    if ((carrier_path[k] - planned_load).norm() < (carrier_path[nearest] - planned_load).norm()) nearest = k;
  std::vector<Eigen::Vector2d> route{load};
  for (size_t k = nearest + 1; k < carrier_path.size(); ++k) route.push_back(carrier_path[k]);
  route.push_back(load_end);
  route = distinct(route);
  if (route.size() < 2) route.push_back(load);  // at its end: a route of no length
  return route;
}

std::vector<Eigen::Vector2d> routeOnFrom(const std::vector<Eigen::Vector2d>& route, const Eigen::Vector2d& load) {
  const OnRoute at = onRoute(route, load);
  const Eigen::Vector2d aim = pushAim(route, at);
  const OnRoute aim_at = onRoute(route, aim);
  std::vector<Eigen::Vector2d> out{load};
  if (!pastEnd(route, aim_at)) out.push_back(aim);  // else straight on to the end, not past it and back
  for (size_t k = aim_at.leg; k < route.size(); ++k) out.push_back(route[k]);
  out = distinct(out);
  if (out.size() < 2) out.push_back(load);
  return out;
}

bool pushMayStartHere(const Eigen::Vector2d& carrier, const Eigen::Vector2d& load,
                      const std::vector<Eigen::Vector2d>& route, double contact_m,
                      const std::vector<PushObstacle>& standing) {
  const Eigen::Vector2d contact = load - carrier;
  if (contact.norm() > contact_m + kPushClearanceM / 3 || contact.norm() < 1e-9 || route.size() < 2) return false;
  const OnRoute at = onRoute(route, load);
  const Eigen::Vector2d aim = pushAim(route, at) - load;
  if (aim.norm() < 1e-9) return true;  // at its end: nothing to run into
  return std::abs(contactDrift(contact, load, route, at)) <= kPushConeRad &&
         !normalRunsIntoBody(load, contact.normalized(), aim.normalized(), standing);
}

std::optional<PushCommand> pushWheels(const Pose2D& carrier, const Eigen::Vector2d& load,
                                      const std::vector<Eigen::Vector2d>& route, double contact_m,
                                      const FollowerGains& gains, bool pushing,
                                      const std::vector<PushObstacle>& standing) {
  const Eigen::Vector2d contact = load - carrier.position();
  if (contact.norm() > contact_m + kPushClearanceM / 3 || contact.norm() < 1e-9 || route.size() < 2)
    return std::nullopt;
  PushCommand out;
  const OnRoute at = onRoute(route, load);
  if (pastEnd(route, at)) {
    out.load_arrived = true;
    return out;
  }
  // The load heads for its route kPushLookaheadM ahead of where it is along it.
  const double drift = contactDrift(contact, load, route, at);
  if (pushing ? std::abs(drift) > kMaxPushLeadRad
              : !pushMayStartHere(carrier.position(), load, route, contact_m, standing))
    return std::nullopt;
  const double normal = std::atan2(contact.y(), contact.x());
  const double lead = std::clamp(kPushLead * drift, -kMaxPushLeadRad, kMaxPushLeadRad);
  const double alpha = wrapAngle(normal + lead - carrier.yaw);
  double v = 0, turn = std::clamp(gains.heading_gain * alpha, -gains.max_turn_rate_radps, gains.max_turn_rate_radps);
  if (std::abs(alpha) <= gains.rotate_in_place_rad) {
    const double ramp = std::min(1.0, (route.back() - load).norm() / gains.slowdown_radius_m);
    // As slow as the load heads off where it should: the over-steer then moves the carrier
    // round the load's side (turning their contact back) before the push drags the load on
    // off its route; at kMaxPushLeadRad it only turns.
    const double on_course = std::max(0.0, 1.0 - std::abs(drift) / kMaxPushLeadRad);
    v = std::max(gains.min_speed_mps, gains.cruise_speed_mps * ramp) * std::max(0.0, std::cos(alpha)) * on_course;
  }
  out.wheels = twistToWheels(v, turn, gains.wheel_base_m);
  const double peak = std::max(std::abs(out.wheels.left_mps), std::abs(out.wheels.right_mps));
  if (peak > gains.max_wheel_speed_mps) {
    out.wheels.left_mps *= gains.max_wheel_speed_mps / peak;
    out.wheels.right_mps *= gains.max_wheel_speed_mps / peak;
  }
  return out;
}

bool behindLoad(const Eigen::Vector2d& carrier, const Eigen::Vector2d& load,
                const std::vector<Eigen::Vector2d>& route) {
  const Eigen::Vector2d contact = load - carrier;
  if (contact.norm() < 1e-9 || route.size() < 2) return false;
  const OnRoute at = onRoute(route, load);
  return pastEnd(route, at) || std::abs(contactDrift(contact, load, route, at)) <= kPushConeRad;
}

std::optional<int> pushedLoad(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                              const std::vector<Eigen::Vector2d>& decided) {
  const int k = task::ridingLoad(spec, step, i, decided);
  if (k < 0) return std::nullopt;
  return step[static_cast<size_t>(k)].entity;
}

PushObstacle pushObstacle(const Eigen::Vector2d& centre, double carrier_contact_m, double load_contact_m) {
  return {centre, std::max(carrier_contact_m, load_contact_m) + kPushPassM};
}

std::vector<PushObstacle> pushObstacles(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                                        int load, const std::vector<Eigen::Vector2d>& at) {
  const int n = static_cast<int>(spec.entities.size());
  std::vector<bool> moves(static_cast<size_t>(n), false);
  for (size_t k = 0; k < step.size(); ++k) {
    if (!step[k].isMotion()) continue;
    moves.at(static_cast<size_t>(step[k].entity)) = true;
    if (const auto riding = pushedLoad(spec, step, k, at)) moves.at(static_cast<size_t>(*riding)) = true;
  }
  const int carrier = step.at(i).entity;
  moves.at(static_cast<size_t>(load)) = true;
  std::vector<PushObstacle> out;
  for (int e = 0; e < n; ++e) {
    const Eigen::Vector2d& p = at.at(static_cast<size_t>(e));
    if (moves[static_cast<size_t>(e)] || !spec.footprint(e).obstacle || !p.allFinite()) continue;
    out.push_back(pushObstacle(p, spec.contactDistance(carrier, e), spec.contactDistance(load, e)));
  }
  return out;
}

std::vector<Eigen::Vector2d> drivenPath(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                                        const std::vector<Eigen::Vector2d>& decided,
                                        const std::vector<Eigen::Vector2d>& ends,
                                        std::vector<Eigen::Vector2d> planned) {
  const auto load = pushedLoad(spec, step, i, decided);
  if (!load || planned.empty()) return planned;
  const auto l = static_cast<size_t>(*load);
  const int carrier = step.at(i).entity;
  return pushPath(planned.front(), decided.at(l), ends.at(l), spec.contactDistance(carrier, *load),
                  ends.at(static_cast<size_t>(carrier)), static_cast<int>(planned.size()),
                  pushObstacles(spec, step, i, *load, decided));
}

Eigen::Vector2d carrierEnd(const Eigen::Vector2d& push_end, const Eigen::Vector2d& load_end,
                           const Eigen::Vector2d& load_at, bool loads_ride) {
  const Eigen::Vector2d away = push_end - load_end;
  if (loads_ride) return push_end;
  if (away.norm() < 1e-9) return load_at;
  return load_at + away + away.normalized() * kPushBackOffM;
}

}  // namespace ddace::exec
