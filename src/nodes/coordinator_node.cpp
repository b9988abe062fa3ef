// coordinator: ddace::nodes::CoordinatorNode (include/ddace/ros/coordinator.h) as a process.
#include "ddace/ros/coordinator.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::CoordinatorNode>(argc, argv, "coordinator");
}
