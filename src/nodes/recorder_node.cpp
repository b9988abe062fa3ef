// recorder_node: ddace::nodes::RecorderNode (include/ddace/ros/recorder.h) as a process.
#include "ddace/ros/recorder.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::RecorderNode>(argc, argv, "recorder_node");
}
