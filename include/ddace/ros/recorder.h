// recorder_node: records tracked entities and the current labels into a ddace-task/1
// task directory (ddace::vision::DemoRecorder does the files; see docs/vision.md).
//
// In:  /ddace/entities (ddace/EntityArray), /ddace/labels (ddace/Label).
// Services: ~start, ~stop, ~discard (std_srvs/Trigger). Out: ~state (std_msgs/String,
// latched): what the recorder is doing, for the labelling tool and people.
// Rows are sampled at rate_hz from the latest EntityArray; a row's t is that message's
// stamp minus the first row's (so positions and times belong together).
#pragma once

#include <memory>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The recorder_node node (src/nodes/recorder_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class RecorderNode {
 public:
  RecorderNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~RecorderNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
