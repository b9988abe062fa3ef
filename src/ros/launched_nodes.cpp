// ddace::ros_launch: see launched_nodes.h.
#include "launched_nodes.h"

#include <cctype>

#include <ros/master.h>
#include <ros/network.h>
#include <ros/param.h>
#include <ros/this_node.h>
#include <xmlrpcpp/XmlRpc.h>

namespace ddace::ros_launch {
namespace {

/// Calls `method` at `uri`; false when it cannot be reached or answers with a fault.
bool call(const std::string& uri, const std::string& method, const XmlRpc::XmlRpcValue& args,
          XmlRpc::XmlRpcValue& result) {
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(uri, host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  return client.execute(method.c_str(), args, result) && !client.isFault();
}

/// The names of the processes every roslaunch of this graph reports ended.
std::vector<std::string> endedProcesses() {
  std::vector<std::string> out;
  XmlRpc::XmlRpcValue uris;
  if (!ros::param::get("/roslaunch/uris", uris) || uris.getType() != XmlRpc::XmlRpcValue::TypeStruct) return out;
  for (auto it = uris.begin(); it != uris.end(); ++it) {
    if (it->second.getType() != XmlRpc::XmlRpcValue::TypeString) continue;
    XmlRpc::XmlRpcValue args, result;
    args.setSize(0);
    // (code, message, [[active (name, spawns)...], [ended (name, spawns)...]])
    if (!call(it->second, "list_processes", args, result) || result.getType() != XmlRpc::XmlRpcValue::TypeArray ||
        result.size() != 3 || result[2].getType() != XmlRpc::XmlRpcValue::TypeArray || result[2].size() != 2)
      continue;
    XmlRpc::XmlRpcValue& ended = result[2][1];
    if (ended.getType() != XmlRpc::XmlRpcValue::TypeArray) continue;
    for (int i = 0; i < ended.size(); ++i)
      if (ended[i].getType() == XmlRpc::XmlRpcValue::TypeArray && ended[i].size() >= 1 &&
          ended[i][0].getType() == XmlRpc::XmlRpcValue::TypeString)
        out.push_back(static_cast<std::string>(ended[i][0]));
  }
  return out;
}

/// roslaunch names node /ns/name's process "ns/name-<counter>".
bool isProcessOf(const std::string& process, const std::string& node) {
  const std::string stem = node.substr(node.rfind('/', 0) == 0 ? 1 : 0) + "-";
  if (process.size() <= stem.size() || process.compare(0, stem.size(), stem) != 0) return false;
  for (size_t i = stem.size(); i < process.size(); ++i)
    if (!std::isdigit(static_cast<unsigned char>(process[i]))) return false;
  return true;
}

/// Whether `node` is registered with the master and answers getPid at its address.
bool answers(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false) ||
      payload.getType() != XmlRpc::XmlRpcValue::TypeString)
    return false;
  XmlRpc::XmlRpcValue ping, pid;
  ping[0] = ros::this_node::getName();
  return call(static_cast<std::string>(payload), "getPid", ping, pid);
}

}  // namespace

std::map<std::string, std::string> endedNodes(const std::vector<std::string>& nodes) {
  std::map<std::string, std::string> out;
  const std::vector<std::string> ended = endedProcesses();
  for (const auto& node : nodes)
    for (const auto& process : ended)
      if (isProcessOf(process, node) && !out.count(node) && !answers(node)) out[node] = process;
  return out;
}

}  // namespace ddace::ros_launch
