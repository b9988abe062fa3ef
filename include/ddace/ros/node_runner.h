// The one main() of every ddace node executable (src/nodes/*_node.cpp).
//
// A node class (include/ddace/ros/*.h) is constructed from the public and private node
// handles and throws ddace::Error when it refuses its configuration. A class with a
// `void run()` main loop (an I/O or simulation loop, a capture loop) gets it called on
// the main thread while one spinner thread serves the callbacks; any other class is
// spun. An exception ends the process with the node's name and the reason on stderr
// (ROS_FATAL) and exit status 1, never a crash or a silent exit 0.
#pragma once

#include <exception>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <ros/ros.h>

namespace ddace::nodes {

namespace detail {
template <typename Node, typename = void>
struct HasRun : std::false_type {};
template <typename Node>
struct HasRun<Node, std::void_t<decltype(std::declval<Node&>().run())>> : std::true_type {};
}  // namespace detail

/// The parameters set under the private namespace `pnh` before the node class is
/// constructed (the user's: launch file, command line, a loaded YAML).
std::vector<std::string> givenParams(const ros::NodeHandle& pnh);
/// Throws ddace::Error naming every parameter of `given` that the node did not read
/// (src/ros/params.h): called once the node class is constructed, so a misspelt or
/// misplaced parameter stops the node instead of leaving it on a default.
void rejectUnknownParams(const ros::NodeHandle& pnh, const std::vector<std::string>& given);

/// False (the reason on stderr) when the launch asked for one machine (environment
/// DDACE_NETWORK=loopback, which the launch files set for their nodes) but this process
/// runs on the host's network: roscpp's XML-RPC server, started with the first
/// NodeHandle, would listen on every interface (docs/trust-boundary.md). Asked before.
bool networkAsLaunched(const char* default_name);

/// ros::init as `default_name`, construct Node (its parameters checked:
/// rejectUnknownParams), run or spin it until shutdown. Returns the process exit status.
template <typename Node>
int runNode(int argc, char** argv, const char* default_name) {
  if (!networkAsLaunched(default_name)) return 1;
  ros::init(argc, argv, default_name);
  // Held for the whole run: when the last NodeHandle goes, roscpp shuts down (and with it
  // rosconsole, which would swallow the error below).
  ros::NodeHandle nh, pnh("~");
  try {
    const std::vector<std::string> given = givenParams(pnh);
    Node node(nh, pnh);
    rejectUnknownParams(pnh, given);
    if constexpr (detail::HasRun<Node>::value) {
      ros::AsyncSpinner spinner(1);  // declared after the node: stops before it is destroyed
      spinner.start();
      node.run();
    } else {
      ros::spin();
    }
  } catch (const std::exception& e) {
    ROS_FATAL("%s: %s", ros::this_node::getName().c_str(), e.what());
    return 1;
  }
  return 0;
}

}  // namespace ddace::nodes
