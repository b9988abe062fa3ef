// hamster_bridge_node: drives real Hamster robots through their USB radio dongles
// (or, for robots with `transport: ble`, directly through BlueZ).
//
// Parameters (private):
//   ~config   (string, required)  path of config/hamsters.yaml (robots, addresses, calibration)
//   ~port_dir (string, optional)  overrides the config's port_dir
//   ~scan     (string list, optional) overrides the config's scan patterns ([] = hints only)
//   ~robots   (string list, optional) drive only these robots of the config
//   ~mock_link_dir (string, optional) a rehearsal: drive only the mock Hamsters' links in this
//             directory (hamster::useMockLinks: port hints, scan and transports of the config
//             ignored), and only while the directory's claim is held by the mock node of this
//             graph, whose pid it states as ~mock_node/pid; anything else is not opened
//   ~mock_node (string, default: mock_hamster beside this node) the mock node of this run
//   ~diagnostic_period (double, default 1.0) diagnostics publication period, s
// Per robot <name>:
//   subscribes /robots/<name>/wheels  (ddace/WheelCommand, m/s per wheel)
//              /robots/<name>/effects (ddace/HamsterEffects, LEDs and sound)
//   publishes  /robots/<name>/sensors (ddace/HamsterSensors, one per sensor line)
//   and one diagnostic status "hamster <name>" on /diagnostics.
// All protocol and safety logic lives in ddace::hamster::RobotLink (core); this node
// only moves messages in and out and runs the I/O loop.
#pragma once

#include <memory>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The hamster_bridge node (src/nodes/hamster_bridge_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class HamsterBridgeNode {
 public:
  HamsterBridgeNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~HamsterBridgeNode();

  /// The node's main loop (on the calling thread; callbacks run on a spinner of their
  /// own). Returns when ROS shuts down.
  void run();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
