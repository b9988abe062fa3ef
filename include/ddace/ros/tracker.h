// tracker_node: overhead camera images -> /ddace/entities, tf table -> <entity>, a debug
// image and rviz markers. The algorithm is ddace::vision::Tracker; this node only
// moves data (see docs/vision.md for topics and parameters).
//
// Sources: image_transport topic `image_raw`, or, when ~video_device >= 0 or
// ~video_file is set, OpenCV's V4L2 / file capture (the frames are then published on
// `image_raw`, with `camera_info` when intrinsics are known, while somebody
// subscribes, e.g. rosbag). Video-file frames are stamped with the file's own time
// line (its first frame at the start of playback).
// Intrinsics, in every input mode: ~camera_calibration_file (camera_info YAML as ROS
// camera calibration writes it), else ~camera_matrix (+ ~distortion), else the
// `camera_info` topic. Without them the node warns once with the error raised markers
// get at the configured height. Diagnostics: one status "tracker" (table frame and its
// reprojection error, height correction, stale entities).
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The tracker_node node (src/nodes/tracker_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class TrackerNode {
 public:
  /// The node's own parameters and their defaults (the detector's and filter's are
  /// config/tracker.yaml's, read by vision::loadTrackerConfig).
  struct Params {
    std::string frame_id = kTableFrame;  ///< frame of the entities, tf parent
    bool publish_tf = true;              ///< tf frame_id -> <entity> for every fresh entity
    int video_device = -1;               ///< V4L2 device number; < 0 = none
    int video_width = 0;                 ///< requested capture size; 0 = the device's
    int video_height = 0;
    double video_rate_hz = 30.0;  ///< frames read per second when the source reports no rate
  };

  TrackerNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~TrackerNode();

  /// Whether frames come from ~video_device / ~video_file (opened by the constructor)
  /// rather than from the `image_raw` subscription.
  bool capturing() const;

  /// The capture loop: reads, publishes and tracks frames on the calling thread until
  /// shutdown, stop() or the end of the video file. Without a capture source it waits
  /// for shutdown (the subscription's callbacks run on the spinner).
  void run();

  /// Ends run() after the current frame (from another thread; the nodelet's unload).
  void stop();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
