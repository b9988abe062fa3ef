// sequence: ddace::nodes::SequenceNode (include/ddace/ros/sequence.h) as a process.
#include "ddace/ros/sequence.h"
#include "ddace/ros/node_runner.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::SequenceNode>(argc, argv, "sequence");
}
