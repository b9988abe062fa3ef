// gp_path: ddace::nodes::GpPathNode (include/ddace/ros/gp_path.h) as a process.
#include "ddace/ros/gp_path.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::GpPathNode>(argc, argv, "gp_path");
}
