// carried_objects: ddace::nodes::CarriedObjectsNode (include/ddace/ros/carried_objects.h) as a process.
#include "ddace/ros/carried_objects.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::CarriedObjectsNode>(argc, argv, "carried_objects");
}
