// coordinator_node: runs a learned task event-driven (exec::Coordinator over ROS).
//
//   in   /ddace/entities (EntityArray), /ddace/decision (Decision), /ddace/path (PathResponse),
//        /robots/E/segment_status (SegmentStatus) for every robot and object E,
//        /robots/R/wheels (the follower's commands: its heartbeat), <node>/heartbeat
//        (Heartbeat) of the sequence, path and recorder roles' nodes,
//        /ddace/estop (std_msgs/Bool, latched; true from anyone e-stops the run)
//   out  /ddace/decision_request, /ddace/path_request, /robots/E/segment,
//        /robots/R/wheels (zeros, when a role is lost or on ~estop), /ddace/estop (latched),
//        ~state (CoordinatorState, latched, every change and ~state_rate_hz), ~markers (MarkerArray)
//   srv  ~start, ~pause, ~reset, ~estop (std_srvs/Trigger)
//
// Decisions are requested and tokens started as exec::Coordinator decides under ~dispatch
// (steps: when every active entity reported its segment done and is tracked at its goal;
// async: each token when its own predecessors have, exec/dispatch.h); the timers check
// time-outs, re-send what is unacknowledged (exec::Outbox) and watch the node of every
// role in ~roles (exec::RoleWatch): a lost one (gone, silent for heartbeat_timeout_s, or
// reporting a problem on its heartbeat) stops every robot and aborts the run; a run starts
// only once every role's node is linked and its heartbeat heard.
// Whenever a segment is cancelled (abort, e-stop, pause, reset, a lost role) the
// coordinator publishes zero wheels for its robot itself in the same callback, before the
// STOP segment: the follower may be the node that died. A subscriber's link dropping
// (a node killed) is acted on in its disconnect callback, not at the next check. A new run
// starts only when ~roles/recorder (if set) answers its ~ready: the record holds the run
// from its first message.
// Parameters: config/execution.yaml, section coordinator.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The coordinator node (src/nodes/coordinator_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class CoordinatorNode {
 public:
  /// The node's own parameters (private namespace) and their defaults, as
  /// config/execution.yaml (section coordinator) documents them; the state machine's
  /// time-outs and step limit are exec::CoordinatorConfig's. arrival_radius_m defaults
  /// to the task's arrival_radius.
  struct Params {
    std::string frame_id = kTableFrame;  ///< frame of paths, goals and markers
    bool autostart = false;              ///< start as soon as every entity is tracked
    double start_timeout_s = 60.0;       ///< autostart: not started this long after the node came up ->
                                         ///< the run is aborted naming what it waited for (0 = wait on)
    int path_points = 100;               ///< points per requested path
    double timeout_check_hz = 50.0;      ///< how often time-outs are checked (the control rate: a
                                         ///< time-out stops the robots within one cycle)
    double resend_after_s = 1.0;         ///< an unacknowledged request or segment goes out again after this
    double state_rate_hz = 5.0;          ///< ~state goes out at this rate (and on every change)
    double liveness_check_hz = 50.0;     ///< how often the roles' nodes are checked
    double heartbeat_timeout_s = 1.0;  ///< roles/: a follower (wheels) or a node's ~heartbeat silent this long is lost
    double pose_timeout_s = 1.0;       ///< roles/: no /ddace/entities from the pose source this long: lost
  };

  CoordinatorNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~CoordinatorNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
