// synthetic_camera_node (test helper): renders the true entity poses into overhead
// camera images so the real tracker can run in tests and simulations.
//
// In:  `true_entities` (ddace/EntityArray; e.g. mock_robot_node's output remapped to
//      /ddace/true_entities, or a test's scripted poses).
// Out: `image_raw` (mono8) + `camera_info` (image_transport camera publisher).
// Each frame shows the latest truth and carries its stamp, so the tracker's output
// can be compared with the truth at exactly that time; a frame is rendered only when a
// newer truth arrived (the camera never publishes two frames with one stamp).
// Bodies are drawn as the task states their footprints (~task: a task directory or its
// task.yaml, absolute path; optional: without it, the default footprint of each kind).
// An entity whose truth says visible = false gets a hand drawn over it (tests script
// occlusions this way, to the frame); occlusion times in the camera file count from the
// first truth message.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The synthetic_camera_node node (src/nodes/synthetic_camera_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class SyntheticCameraNode {
 public:
  /// The node's own parameters and their defaults (the camera itself: ~camera_file).
  struct Params {
    std::string frame_id = kCameraFrame;  ///< frame of the images and camera_info
    double rate_hz = 30.0;                ///< at most this many frames per second, (0, 1000]
  };

  SyntheticCameraNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~SyntheticCameraNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
