// carried_objects_node: the executor of objects on the real table, where nothing but a
// carrier moves a box. Each object's segment (/robots/<O>/segment) is judged from tracking
// by an exec::CarriedObjects (include/ddace/exec/carried_objects.h): done when the tracker
// (/ddace/entities) sees the object at its end point and its carrier's follower reported
// its segment done (/robots/<R>/segment, /robots/<R>/segment_status), failed naming the
// object otherwise; reported on /robots/<O>/segment_status. This node only reads the
// parameters and converts messages.
//
// At start it refuses (exits naming the token) a task whose demonstrations move an object
// with no robot carrying it in the same step (exec::uncarriedObjectMotion): on the real
// table nothing would move it. Parameters (private): task (absolute path of the task
// directory or task.yaml; the check needs its demos/), settle_s, pairing_s
// (exec::CarriedObjectParams), entities_topic.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

#include "ddace/exec/carried_objects.h"

namespace ddace::nodes {

class CarriedObjectsNode {
 public:
  struct Params {
    double settle_s = exec::CarriedObjectParams{}.settle_s;
    double pairing_s = exec::CarriedObjectParams{}.pairing_s;
    std::string entities_topic = "/ddace/entities";
    double rate_hz = 10;  ///< time-outs are checked at this rate when no tracker message comes
  };

  /// Throws ddace::Error naming the parameter or file it refuses, or the token no robot
  /// carries.
  CarriedObjectsNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~CarriedObjectsNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
