// sim_table_node: one simulated table with bodies in place of the real one, for
// rehearsing without hardware (launch/execute_real.launch and launch/record.launch with
// sim:=true). The table is an exec::SimTable (include/ddace/exec/sim_table.h): robots on
// their wheels, objects pushed by the bodies that meet them, nothing moved by a segment.
//
// In: the robots' wheel speeds, by ~wheels:
//   mock_hamster  ~mock_state_topic (ddace/HamsterMockState, default /mock_hamster/state):
//                 what the protocol-level mock Hamsters' wheels do (left_mps, right_mps),
//                 driven by the real hamster_bridge over their pseudo-terminals;
//   commands      /robots/<R>/wheels (ddace/WheelCommand): a teleop or a test driving the
//                 simulated robots directly, from the nodes ~command_sources names only
//                 (as the robots' drivers: src/ros/command_sources.h).
//   A robot whose speeds stop coming stops after ~robot/command_timeout_s.
// Out: `true_entities` (ddace/EntityArray, default /ddace/true_entities): every entity's
// true pose each step, for synthetic_camera_node, whose images the tracker measures.
// Parameters (private): the task, either ~task (a task directory or its task.yaml,
// absolute) or ~recorder_file + ~markers_file (the task record.launch records); where the
// entities start:
// ~scene_demo / ~scene_csv (a demonstration's first row), else laid out in rows between
// the corner markers of ~markers_file (or on ~table_size [width, depth] m from the
// origin, when given or when there are no corners); ~scene (map name: [x, y(, yaw)]) over either;
// ~robot/* (exec::DiffDriveParams); ~frame_id.
// ~drag (bool): a person drags entities in rviz (interactive markers on ~drag/update,
// feedback on ~drag/feedback; exec::SimTable::drag: robots drive to where they are dropped,
// boxes and goals are carried there, nothing teleports). Drags ending short are logged.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <ros/node_handle.h>

#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The sim_table node (src/nodes/sim_table_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class SimTableNode {
 public:
  /// The node's own parameters and their defaults.
  struct Params {
    std::string wheels = "mock_hamster";  ///< mock_hamster | commands
    std::string mock_state_topic = "/mock_hamster/state";
    std::string entities_topic = "/ddace/true_entities";
    std::vector<double> table_size{1.0, 1.0};  ///< without corners: as config/markers.yaml's
    std::string frame_id = kTableFrame;
    /// A robot of the task whose wheels are not heard of within this long is reported.
    double wheels_grace_s = 5.0;
    /// Entities dragged in rviz (interactive markers on ~drag/...): record.launch sim:=true.
    bool drag = false;
  };

  SimTableNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~SimTableNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
