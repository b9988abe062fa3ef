// mock_hamster_node: simulated Hamster dongles on pseudo-terminals, for tests and demos
// without hardware. Speaks the radio protocol (ddace::hamster::MockRobot), so the real
// hamster_bridge_node drives it unchanged.
//
// Parameters (private):
//   ~config   (string, required)  the bridge's Hamster config: robot names, addresses,
//                                  models (auto = hamster) and, unless overridden, the true
//                                  wheel speed per unit (= its calibration: a perfect one)
//   ~link_dir (string, required)  directory (created) for the symlinks <link_dir>/hamster_<name>
//                                  → pty slave; point the bridge's port_dir or hints here.
//                                  Claimed for this run (hamster::LinkDirClaim): refused when
//                                  another live run holds it or a link of ours is there already;
//                                  its pid is then set as ~pid, which the bridge's
//                                  ~mock_link_dir checks the claim against
//   ~robots   (string list, optional) simulate only these robots of the config (a name
//             the config does not have stops the node, as in hamster_bridge_node)
//   ~true_mps_per_unit (double, optional) the simulated robots' real speed per unit, to
//                                  test a calibration
//   ~robot_timeout_s (double, default 0) a robot stops after this long without motoring
//                                  lines (0 = keeps the last wheels, the worst case)
//   ~frame_id (string, default "table")
// Topics (private): ~state (ddace/HamsterMockState, per robot, 50 Hz), ~entities
// (ddace/EntityArray, true poses, 30 Hz), ~fault (ddace/HamsterMockFault, in).
#pragma once

#include <memory>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The mock_hamster node (src/nodes/mock_hamster_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class MockHamsterNode {
 public:
  MockHamsterNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~MockHamsterNode();

  /// The node's main loop (on the calling thread; callbacks run on a spinner of their
  /// own). Returns when ROS shuts down.
  void run();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
