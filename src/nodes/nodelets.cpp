// The camera -> tracker path as nodelets (library ddace_nodelets, nodelet_plugins.xml):
// ddace/SyntheticCamera and ddace/Tracker are the classes of synthetic_camera_node and
// tracker_node, loaded into one nodelet manager so images pass by pointer instead of
// being serialised. `roslaunch ddace record.launch nodelet:=true` (and
// execute_real.launch) run them this way.
#include <exception>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include "ddace/ros/node_runner.h"
#include "ddace/ros/synthetic_camera.h"
#include "ddace/ros/tracker.h"

namespace ddace::nodes {

/// A nodelet holding one node class, constructed from the nodelet's handles.
template <typename Node>
class NodeNodelet : public nodelet::Nodelet {
 protected:
  /// A refused configuration is logged with the nodelet's name and rethrown, so the
  /// manager refuses the load (and `nodelet load` exits non-zero) instead of running
  /// half a node.
  void construct() {
    try {
      const std::vector<std::string> given = givenParams(getPrivateNodeHandle());
      node_ = std::make_unique<Node>(getNodeHandle(), getPrivateNodeHandle());
      rejectUnknownParams(getPrivateNodeHandle(), given);
    } catch (const std::exception& e) {
      ROS_FATAL("%s: %s", getName().c_str(), e.what());
      throw;
    }
  }

  std::unique_ptr<Node> node_;
};

class SyntheticCameraNodelet : public NodeNodelet<SyntheticCameraNode> {
 private:
  void onInit() override { construct(); }
};

class TrackerNodelet : public NodeNodelet<TrackerNode> {
 public:
  ~TrackerNodelet() override {
    if (capture_.joinable()) {
      node_->stop();
      capture_.join();
    }
  }

 private:
  void onInit() override {
    construct();
    // A device or file is read on a thread of the nodelet's own; images from a topic
    // come through the manager's callback queue like any other.
    if (node_->capturing())
      capture_ = std::thread([this] {
        try {
          node_->run();
        } catch (const std::exception& e) {
          ROS_FATAL("%s: capture stopped: %s", getName().c_str(), e.what());
        }
      });
  }

  std::thread capture_;
};

}  // namespace ddace::nodes

PLUGINLIB_EXPORT_CLASS(ddace::nodes::SyntheticCameraNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(ddace::nodes::TrackerNodelet, nodelet::Nodelet)
