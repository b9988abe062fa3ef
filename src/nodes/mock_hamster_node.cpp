// mock_hamster: ddace::nodes::MockHamsterNode (include/ddace/ros/mock_hamster.h) as a process.
#include "ddace/ros/mock_hamster.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::MockHamsterNode>(argc, argv, "mock_hamster");
}
