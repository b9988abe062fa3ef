// hamster_bridge: ddace::nodes::HamsterBridgeNode (include/ddace/ros/hamster_bridge.h) as a process.
#include "ddace/ros/hamster_bridge.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::HamsterBridgeNode>(argc, argv, "hamster_bridge");
}
