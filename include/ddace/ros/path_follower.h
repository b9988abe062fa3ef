// path_follower_node: drives every robot of the task along its current segment with the
// pure-pursuit-with-progress law of exec::PathFollower, from the tracked poses. Each
// robot's command passes through its own exec::SafetyFilter (exec/safety_filter.h), fed
// with the tracked poses of every other body on /ddace/entities (robots, objects, idle or
// not): no two bodies closer than contact + ~safety/margin_m, except the segment's target.
//
// Per robot R:  in  /robots/R/segment (ddace/Segment), /ddace/entities (ddace/EntityArray)
//               out /robots/R/wheels (ddace/WheelCommand, every control cycle),
//                   /robots/R/segment_status (ddace/SegmentStatus)
// Global:       in  /ddace/estop (std_msgs/Bool, latched): true zeroes every robot at once.
//
// Fails safe: no segment, a stale or missing pose, an e-stop, a stop segment, arrival,
// the coordinator gone (no publisher left on /robots/R/segment, checked every cycle): zero
// wheels. The e-stop, a STOP segment and a pose flagged stale zero the wheels in the
// callback that receives them, so within the control cycle under way. A pose that stays
// stale for stale_fail_s fails the segment; so does a stale body near the robot (the
// filter zeroes the wheels) and a deadlock the filter reports (the status names the robot
// and the bodies that block it).
// Parameters: config/execution.yaml, section path_follower.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The path_follower node (src/nodes/path_follower_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class PathFollowerNode {
 public:
  /// The node's own parameters (private namespace) and their defaults, as
  /// config/execution.yaml (section path_follower) documents them; ~gains/* are
  /// exec::FollowerGains (stop_radius_m defaults to task::stopRadius of the task's arrival_radius).
  struct Params {
    double rate_hz = 50.0;         ///< control cycle; wheel commands go out every cycle
    double pose_timeout_s = 0.25;  ///< no pose of a robot for this long = stale -> zero wheels
    double stale_fail_s = 2.0;     ///< stale for this long during a segment -> segment FAILED
    int status_every_cycles = 5;   ///< RUNNING status every N cycles
    /// The table carries a load in front of its carrier once met (mock robots) instead of
    /// leaving it to be pushed (exec::MotionContacts::load_rides).
    bool loads_ride = false;
  };

  PathFollowerNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~PathFollowerNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
