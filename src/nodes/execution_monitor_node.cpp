// execution_monitor: ddace::nodes::ExecutionMonitorNode (include/ddace/ros/execution_monitor.h) as a process.
#include "ddace/ros/execution_monitor.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::ExecutionMonitorNode>(argc, argv, "execution_monitor");
}
