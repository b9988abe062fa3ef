// tracker_node: ddace::nodes::TrackerNode (include/ddace/ros/tracker.h) as a process.
#include "ddace/ros/tracker.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::TrackerNode>(argc, argv, "tracker_node");
}
