// mock_robots: ddace::nodes::MockRobotNode (include/ddace/ros/mock_robot.h) as a process.
#include "ddace/ros/mock_robot.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::MockRobotNode>(argc, argv, "mock_robots");
}
