#include "ddace/exec/push_path.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/angle.h"
#include "ddace/exec/path_follower.h"

#include "ddace/task/end_point.h"

namespace ddace::exec {

namespace {

Eigen::Vector2d onCircle(const Eigen::Vector2d& centre, double radius, double angle) {
  return centre + radius * Eigen::Vector2d(std::cos(angle), std::sin(angle));
}

/// The push line's direction: through `load_end`, from `carrier_end` behind it (or along
/// `fallback` when they coincide).
Eigen::Vector2d pushDirection(const Eigen::Vector2d& load_end, const Eigen::Vector2d& carrier_end,
                              const Eigen::Vector2d& fallback) {
  const Eigen::Vector2d line = load_end - carrier_end;
  return line.norm() > 1e-9 ? Eigen::Vector2d(line.normalized()) : fallback.normalized();
}

/// How far the contact normal `contact` (carrier to load) turns from where the load should
/// head: for the push line kPushLookaheadM ahead of the load (`along` < 0 short of its end).
double contactDrift(const Eigen::Vector2d& contact, const Eigen::Vector2d& load, const Eigen::Vector2d& load_end,
                    const Eigen::Vector2d& w, double along) {
  const Eigen::Vector2d aim = load_end + (along + kPushLookaheadM) * w - load;
  return wrapAngle(std::atan2(contact.y(), contact.x()) - std::atan2(aim.y(), aim.x()));
}

}  // namespace

std::vector<Eigen::Vector2d> pushPath(const Eigen::Vector2d& from, const Eigen::Vector2d& load,
                                      const Eigen::Vector2d& load_end, double contact_m,
                                      const Eigen::Vector2d& fallback_end, int points) {
  const auto evenly = [&](std::vector<Eigen::Vector2d> corners) {
    return resampleByArcLength(PlannedPath{std::move(corners), {}}, std::max(points, 2)).points;
  };
  const Eigen::Vector2d push = load_end - load;
  if (push.norm() < task::kMinApproachM) return evenly({from, fallback_end});
  const Eigen::Vector2d w = push.normalized();
  const double radius = contact_m + kPushClearanceM;
  const double behind = std::atan2(-w.y(), -w.x());  // the run-up's bearing from the load
  std::vector<Eigen::Vector2d> out{from};
  const Eigen::Vector2d rel = from - load;
  if (rel.norm() > 1e-9) {
    // Out to the circle (or in, from afar), round it the shorter way to the run-up.
    const double bearing = std::atan2(rel.y(), rel.x());
    const double turn = wrapAngle(behind - bearing);
    const int steps = static_cast<int>(std::ceil(std::abs(turn) / kPushArcStepRad));
    for (int k = 0; k <= steps; ++k) out.push_back(onCircle(load, radius, bearing + turn * k / std::max(steps, 1)));
  } else {
    out.push_back(onCircle(load, radius, behind));
  }
  out.push_back(load_end - contact_m * w);
  return evenly(std::move(out));
}

std::optional<PushCommand> pushWheels(const Pose2D& carrier, const Eigen::Vector2d& load,
                                      const Eigen::Vector2d& load_end, const Eigen::Vector2d& carrier_end,
                                      double contact_m, const FollowerGains& gains) {
  const Eigen::Vector2d contact = load - carrier.position();
  if (contact.norm() > contact_m + kPushClearanceM / 3 || contact.norm() < 1e-9) return std::nullopt;
  PushCommand out;
  // The push line runs through the load's end point, from the carrier's end behind it.
  const Eigen::Vector2d w = pushDirection(load_end, carrier_end, contact);
  const double along = (load - load_end).dot(w);  // < 0: short of the end
  if (along >= 0) {
    out.load_arrived = true;
    return out;
  }
  // The load heads for the line kPushLookaheadM ahead of where it is along it.
  const double drift = contactDrift(contact, load, load_end, w, along);
  if (std::abs(drift) > kPushConeRad) return std::nullopt;
  const double normal = std::atan2(contact.y(), contact.x());
  const double lead = std::clamp(kPushLead * drift, -kMaxPushLeadRad, kMaxPushLeadRad);
  const double alpha = wrapAngle(normal + lead - carrier.yaw);
  double v = 0, turn = std::clamp(gains.heading_gain * alpha, -gains.max_turn_rate_radps, gains.max_turn_rate_radps);
  if (std::abs(alpha) <= gains.rotate_in_place_rad) {
    const double ramp = std::min(1.0, -along / gains.slowdown_radius_m);
    v = std::max(gains.min_speed_mps, gains.cruise_speed_mps * ramp) * std::max(0.0, std::cos(alpha));
  }
  out.wheels = twistToWheels(v, turn, gains.wheel_base_m);
  const double peak = std::max(std::abs(out.wheels.left_mps), std::abs(out.wheels.right_mps));
  if (peak > gains.max_wheel_speed_mps) {
    out.wheels.left_mps *= gains.max_wheel_speed_mps / peak;
    out.wheels.right_mps *= gains.max_wheel_speed_mps / peak;
  }
  return out;
}

bool behindLoad(const Eigen::Vector2d& carrier, const Eigen::Vector2d& load, const Eigen::Vector2d& load_end,
                const Eigen::Vector2d& carrier_end) {
  const Eigen::Vector2d contact = load - carrier;
  if (contact.norm() < 1e-9) return false;
  const Eigen::Vector2d w = pushDirection(load_end, carrier_end, contact);
  const double along = (load - load_end).dot(w);
  return along >= 0 || std::abs(contactDrift(contact, load, load_end, w, along)) <= kPushConeRad;
}

std::optional<int> pushedLoad(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i,
                              const std::vector<Eigen::Vector2d>& decided) {
  const int k = task::ridingLoad(spec, step, i, decided);
  if (k < 0) return std::nullopt;
  return step[static_cast<size_t>(k)].entity;
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
                  ends.at(static_cast<size_t>(carrier)), static_cast<int>(planned.size()));
}

}  // namespace ddace::exec
