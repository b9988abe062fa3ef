// Who takes which place when robots meet at one body: the places task::stepEndPositions
// finds round the body (turned about it in token order, where the nearer places are taken)
// are a set; which robot ends at which is decided once per step.
//
// ByLeastTravel (stepEndPositions' rule, wherever a step is executed with bodies: `ddace
// eval` with bodies and the coordinator): robots of one size meeting at one body, none
// carrying a load, take the places by the least total travel round that body (each way the
// shortest that keeps out of the body's contact disc): two whose swapped places shorten it
// swap, until none do. Then no robot's way to its place crosses another's -- two crossing
// ways, swapped where they cross, would be shorter. In token order, a place turned to the
// far side of the met body can go to a robot whose way there passes another's place, and
// each holds the other short of its place.
//
// InTokenOrder: each robot keeps the place found for it -- the generators' demonstrations
// (tasks/generators.h, tasks/rule_zoo.h), which show what they show.
//
// Owns: the assignment of a meeting's places. Units: metres, table frame.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ddace/task/end_point.h"

namespace ddace::task {

enum class MeetingPlaces { ByLeastTravel, InTokenOrder };

/// task::stepEndPositions with the places of a meeting taken as `meetings` says (see above).
std::vector<Eigen::Vector2d> stepEndPositions(const TaskSpec& spec, const EndPointModel& model,
                                              const std::vector<Token>& step,
                                              const std::vector<Eigen::Vector2d>& decided,
                                              const std::optional<Eigen::AlignedBox2d>& table, int step_index,
                                              MeetingPlaces meetings);

}  // namespace ddace::task
