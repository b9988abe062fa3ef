// Message conversions and parameter loaders shared by the execution nodes
// (sequence, gp_path, coordinator, path_follower, mock_robot).
//
// Every conversion that can meet bad input throws ddace::Error naming the topic/field;
// nodes then refuse the message (log + error status), they never act on a default.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <ros/ros.h>

#include <ddace/Decision.h>
#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>
#include <ddace/Token.h>
#include <nav_msgs/Path.h>

#include "ddace/exec/coordinator.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/task/task_dir.h"

namespace ddace::ros_exec {

/// A wheel command stamped now.
ddace::WheelCommand toMsg(const exec::WheelSpeeds& wheels);
/// The SegmentStatus code of an executor's segment state (an executor never reports Sent).
uint8_t statusCode(exec::SegmentState state);
/// The state a SegmentStatus code ends a segment in: Done, Failed or Aborted; nothing for
/// accepted and running.
std::optional<exec::SegmentState> endedState(uint8_t status);
/// A segment status of `entity` stamped now.
ddace::SegmentStatus statusMsg(const std::string& entity, uint32_t segment_id, uint8_t status, double progress,
                               double distance_to_goal_m, const std::string& message);

/// A carried object's segment status (exec::ObjectStatus), stamped now.
ddace::SegmentStatus statusMsg(const exec::ObjectStatus& status, const task::TaskSpec& spec);

/// The task spec from a task directory or a task.yaml path. Throws ddace::Error; a
/// relative path is refused (nodes run in ROS_HOME, not in the caller's directory).
task::TaskSpec loadTaskSpec(const std::string& task_path);

/// Refuses a relative path given in parameter `param`: nodes run in ROS_HOME, so it would
/// not mean what the caller meant. Throws ddace::Error saying so.
void requireAbsolute(const std::string& path, const std::string& param);

/// Token message -> core token. Throws ddace::Error naming the unknown entity/target.
task::Token fromMsg(const ddace::Token& msg, const task::TaskSpec& spec);
/// Token message -> core token, or nothing where fromMsg would throw (a node that refuses
/// or ignores a malformed token says so itself).
std::optional<task::Token> tokenOrNothing(const ddace::Token& msg, const task::TaskSpec& spec);
ddace::Token toMsg(const task::Token& token, const task::TaskSpec& spec, double probability = 1.0);

/// Planned path -> nav_msgs/Path (frame `frame_id`, orientation = direction of travel)
/// plus its progress and stddev arrays.
void toMsg(const exec::PlannedPath& path, const std::string& frame_id, const ros::Time& stamp, nav_msgs::Path& out,
           std::vector<double>& progress, std::vector<double>& stddev_m);
/// nav_msgs/Path (+ stddev, may be empty) -> planned path. Throws ddace::Error on a
/// non-finite coordinate or a stddev array of the wrong length; `what` names the source.
exec::PlannedPath fromMsg(const nav_msgs::Path& path, const std::vector<double>& stddev_m, const std::string& what);

/// Entity array -> observation in `spec`'s entity order. An entity that is missing,
/// stale or whose data is not finite counts as not tracked. Yaws go to `yaws` when given.
exec::EntityObservation toObservation(const ddace::EntityArray& msg, const task::TaskSpec& spec,
                                      std::vector<double>* yaws = nullptr);

/// Follower gains from `~follower/*` style parameters under `nh` (defaults from FollowerGains).
exec::FollowerGains loadFollowerGains(const ros::NodeHandle& nh);
/// exec::SafetyParams from `nh` (the follower's ~safety), defaults where unset; throws
/// ddace::Error naming the invalid parameter and namespace.
exec::SafetyParams loadSafetyParams(const ros::NodeHandle& nh);
/// Diff-drive parameters from parameters under `nh`, exec::simulatedHamster() where unset.
exec::DiffDriveParams loadDiffDriveParams(const ros::NodeHandle& nh);
/// The simulated table's parameters under `nh` (mock_robots: bodies, object_speed_mps,
/// object_damping_hz), `defaults` where unset; throws as above.
exec::TableSimulatorParams loadTableParams(const ros::NodeHandle& nh, const exec::TableSimulatorParams& defaults);

/// Start poses of a simulated table (mock_robots, sim_table), every entity of `spec` in its
/// order: a demonstration's first row (~scene_csv, or the ~scene_demo-th of the task
/// directory `task_path`), else `fallback()` (none: empty), with a ~scene map name ->
/// [x, y] or [x, y, yaw] put over it. Throws ddace::Error naming the parameter at fault,
/// or the first entity left without a pose.
std::vector<exec::Pose2D> loadScene(const ros::NodeHandle& pnh, const task::TaskSpec& spec,
                                    const std::string& task_path,
                                    const std::function<std::vector<exec::Pose2D>()>& fallback = {});

}  // namespace ddace::ros_exec
