// sim_table: ddace::nodes::SimTableNode (include/ddace/ros/sim_table.h) as a process.
#include "ddace/ros/node_runner.h"
#include "ddace/ros/sim_table.h"

int main(int argc, char** argv) {
  return ddace::nodes::runNode<ddace::nodes::SimTableNode>(argc, argv, "sim_table");
}
