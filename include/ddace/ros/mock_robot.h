// mock_robot_node: stands in for the Hamsters, their bridge and the overhead tracker.
//
// The table is an exec::TableSimulator (include/ddace/exec/table_simulator.h): every
// robot of the task is an exec::DiffDriveModel (unicycle at rate_hz, wheel limits, command
// latency, watchdog, pose noise) driven by /robots/R/wheels; objects move only through
// their own segments (/robots/O/segment), following the path ideally at object_speed_mps
// and reporting /robots/O/segment_status, as in the simulator; goals stay put. With
// `bodies`, robots and objects are Box2D discs that collide and push each other, and every
// contact is logged as it begins (the execution monitor counts collisions from the
// tracked poses, on the real table alike). This node
// only reads the parameters and the scene and converts messages. Publishes every entity on `entities_topic` (default
// /ddace/entities; remap it when a synthetic camera + tracker close the loop) and tf table -> entity. Parameters:
// config/execution.yaml, section mock_robots. A hand on the table, for perturbation tests:
// ~place (ddace/Entity: a robot or object put down at pose.x, pose.y, at rest), ~hold and
// ~release (std_msgs/String: a robot's wheels blocked, freed), ~lose (std_msgs/String: a
// robot's battery dies, its wheels stop and its last pose is published stale from then on);
// other names are logged and ignored.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/exec/table_simulator.h"
#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The mock_robots node (src/nodes/mock_robot_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class MockRobotNode {
 public:
  /// The node's own parameters (private namespace) and their defaults, as
  /// config/execution.yaml (section mock_robots) documents them; ~robot/* are
  /// exec::DiffDriveParams; bodies, object_speed_mps, object_damping_hz and loads_ride are
  /// exec::TableSimulatorParams'.
  struct Params : exec::TableSimulatorParams {
    Params() { bodies = true; }  // the mock table has bodies (exec::TableSimulatorParams alone: points)
    std::string frame_id = kTableFrame;
    std::string entities_topic = "/ddace/entities";  ///< remap for a synthetic camera + tracker
    bool publish_tf = true;                          ///< tf table -> <entity> for every entity
  };

  MockRobotNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~MockRobotNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
