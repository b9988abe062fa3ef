// path_follower: ddace::nodes::PathFollowerNode (include/ddace/ros/path_follower.h) as a process.
#include "ddace/ros/path_follower.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::PathFollowerNode>(argc, argv, "path_follower");
}
