// The wheel-command interlock of the nodes that move robots (hamster_bridge, mock_robots):
// ~command_sources names the nodes whose /robots/<R>/wheels commands count
// (ddace/common/command_sources.h has the rule).
#pragma once

#include <string>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <ros/ros.h>

#include <ddace/WheelCommand.h>

#include "ddace/common/command_sources.h"

namespace ddace::ros_command {

/// The allowed publishers of `robot`'s wheel commands from the private parameter
/// ~command_sources: a list of node names for every robot ([/path_follower, /coordinator]),
/// or a map robot -> list (every robot the node drives must have an entry). Required: the
/// launch files set it from the roles they give the nodes. Throws ddace::Error naming the
/// parameter when it is missing, mistyped or empty.
CommandSources load(const ros::NodeHandle& pnh, const std::string& robot);

/// True when the command counts. A refused one is counted in `sources` and warned about
/// (at most once a second per robot) naming the robot, the publisher and why.
bool accept(CommandSources& sources, const ros::MessageEvent<const ddace::WheelCommand>& ev, const std::string& node,
            const std::string& robot);

/// The interlock's account in a robot's diagnostics: "command sources", "foreign commands"
/// ("40, last from /intruder"), "unstamped commands"; the status turns WARN naming the
/// stranger while its commands come (more than `reported_foreign`, the count at the last
/// report, which is updated).
void diagnose(const CommandSources& sources, uint64_t& reported_foreign,
              diagnostic_updater::DiagnosticStatusWrapper& status);

}  // namespace ddace::ros_command
