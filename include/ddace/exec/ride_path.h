// Where a load rides, its carrier drives the path it was shown. A load that rides (the
// simulated and mock Hamsters' model, exec::TableParams::loads_ride) keeps in front of its
// carrier wherever the carrier turns, so the learned primitive's path -- the way people
// carried it -- is a path the pair can drive; going round the load to push it from behind
// (exec/push_path.h) is what a load that is pushed needs, and it would replace the shown
// path by another (a loop round the box before every carry). The shown path is kept where
// it passes the bodies standing in the step as a push would pass them; else the carrier
// pushes round them as exec/push_path.h plans it.
//
// Owns: whether a riding load's carrier may drive its shown path. Must not: plan pushes
// (push_path.h) or decide who carries what (task::ridingLoad). Units: metres, table frame.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ddace/exec/push_path.h"

namespace ddace::exec {

/// The angle between two box positions checked along the swing of a riding load from
/// where it stands to the front of its carrier's first heading (radians).
inline constexpr double kRideSwingStepRad = 0.15;

/// Whether a carrier driving `path` (from its first point) with its load riding in front of
/// it -- the load at `load` when the carrier starts, swinging round to `ride_m` ahead of the
/// carrier along the path -- keeps itself and the load as far from every body of `standing`
/// as a push passes them (their reach_m), or no nearer than each of them is at the start
/// or the end (a relay's giver standing at the load; the robot it is handed to), as a push
/// route passes them. False for a path of fewer than two points.
bool rideIsClear(const std::vector<Eigen::Vector2d>& path, const Eigen::Vector2d& load, double ride_m,
                 const std::vector<PushObstacle>& standing);

/// Whether the carrier of motion `step[i]`, whose load `load` (an entity) rides when
/// `loads_ride`, drives its shown path `planned` rather than pushing the load
/// (drivenPath): the load rides and the ride is clear of the bodies standing while the
/// step runs (pushObstacles at `at`, every entity's position, a non-finite one not known).
/// The simulator and the coordinator decide it with this one rule.
bool drivesShownPath(const task::TaskSpec& spec, const std::vector<task::Token>& step, size_t i, int load,
                     const std::vector<Eigen::Vector2d>& at, const std::vector<Eigen::Vector2d>& planned,
                     bool loads_ride);

}  // namespace ddace::exec
