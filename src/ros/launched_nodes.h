// Which nodes of this graph have ended, as the roslaunch that started them tells.
//
// A node that exits before a run starts leaves no link for the coordinator to see drop; a
// node that was never connected is just "not there yet". roslaunch knows: it registers its
// XML-RPC server under the parameter /roslaunch/uris, and its list_processes names the
// processes that ended and are not respawned ("tracker-3" is node /tracker's).
#pragma once

#include <map>
#include <string>
#include <vector>

namespace ddace::ros_launch {

/// The nodes among `nodes` (absolute names) whose process a roslaunch of this graph
/// reports ended, and that do not answer at their XML-RPC address now (a node started
/// again by hand is alive): node -> roslaunch's process name. Empty when no roslaunch
/// serves the graph or none answers. Blocks for a few XML-RPC calls over loopback.
std::map<std::string, std::string> endedNodes(const std::vector<std::string>& nodes);

}  // namespace ddace::ros_launch
