// synthetic_camera_node: ddace::nodes::SyntheticCameraNode (include/ddace/ros/synthetic_camera.h) as a process.
#include "ddace/ros/synthetic_camera.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::SyntheticCameraNode>(argc, argv, "synthetic_camera_node");
}
