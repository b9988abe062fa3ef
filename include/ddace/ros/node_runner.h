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
#include <type_traits>
#include <utility>

#include <ros/ros.h>

namespace ddace::nodes {

namespace detail {
template <typename Node, typename = void>
struct HasRun : std::false_type {};
template <typename Node>
struct HasRun<Node, std::void_t<decltype(std::declval<Node&>().run())>> : std::true_type {};
}  // namespace detail

/// ros::init as `default_name`, construct Node, run or spin it until shutdown.
/// Returns the process exit status.
template <typename Node>
int runNode(int argc, char** argv, const char* default_name) {
  ros::init(argc, argv, default_name);
  // Held for the whole run: when the last NodeHandle goes, roscpp shuts down (and with it
  // rosconsole, which would swallow the error below).
  ros::NodeHandle nh, pnh("~");
  try {
    Node node(nh, pnh);
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
