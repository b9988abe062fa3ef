// gp_path_node: answers path requests (token key, start, goal) with a progress-
// parameterised path and its per-point standard deviation.
//
//   in  /ddace/path_request (PathRequest)
//   out /ddace/path (PathResponse), ~heartbeat (Heartbeat, ~heartbeat_rate_hz: the
//       coordinator's role watch notices a hung node by its silence)
//
// Path sources (parameter `source`):
//   library        the Gaussian-process primitive library (`library`: a primitives.yaml or a
//                  model directory holding one): gp::PrimitiveLibrary::generate, with the
//                  per-point standard deviation; a key never demonstrated falls back as
//                  gp/primitives.h says and the response says so (fell_back). A model
//                  directory is loaded by pipeline::loadModel (every file verified); a
//                  library of another task than `task` (its task fingerprint) is refused
//                  unless `allow_other_task` is true.
//   demonstration  the first demonstrated trajectory of the token's key in `task`'s demos/,
//                  retargeted to the new start and goal by a similarity transform; zero
//                  standard deviation (one demonstration has no spread).
// Parameters: config/execution.yaml, section gp_path.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/ros/frames.h"

namespace ddace::nodes {

/// The gp_path node (src/nodes/gp_path_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class GpPathNode {
 public:
  /// Where paths come from (parameter `source`: "library" or "demonstration").
  enum class Source { Library, Demonstration };
  /// "library" / "demonstration"; throws ddace::Error naming `param_name` otherwise.
  static Source parseSource(const std::string& value, const std::string& param_name);

  /// The node's own parameters and their defaults (config/execution.yaml, section gp_path).
  struct Params {
    std::string frame_id = kTableFrame;
    Source source = Source::Demonstration;
    int points = 100;               ///< path points when a request does not say
    bool allow_other_task = false;  ///< source library: accept a library of another task
                                    ///< (deliberate transfer) instead of refusing it
  };

  GpPathNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~GpPathNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
