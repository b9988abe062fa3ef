// The wheel-command interlock: see command_sources.h.
#include "command_sources.h"

#include <vector>

#include "params.h"

namespace ddace::ros_command {

namespace {

std::vector<std::string> names(XmlRpc::XmlRpcValue& v, const std::string& where) {
  if (v.getType() != XmlRpc::XmlRpcValue::TypeArray)
    throw Error(where + " must be a list of node names, e.g. [/path_follower, /coordinator]");
  std::vector<std::string> out;
  for (int i = 0; i < v.size(); ++i) {
    if (v[i].getType() != XmlRpc::XmlRpcValue::TypeString)
      throw Error(where + " element " + std::to_string(i) + " is not a node name (a string)");
    out.push_back(static_cast<std::string>(v[i]));
  }
  return out;
}

}  // namespace

CommandSources load(const ros::NodeHandle& pnh, const std::string& robot) {
  const std::string param = pnh.resolveName("command_sources");
  auto value = rosparam::optionalParam<XmlRpc::XmlRpcValue>(pnh, "command_sources");
  if (!value)
    throw Error("parameter '" + param +
                "' is not set: name the nodes whose wheel commands count, e.g. [/path_follower, /coordinator] "
                "(the launch files set it)");
  if (value->getType() == XmlRpc::XmlRpcValue::TypeStruct) {
    if (!value->hasMember(robot)) throw Error("parameter '" + param + "' has no entry for robot " + robot);
    const std::string where = "parameter '" + param + "/" + robot + "'";
    return CommandSources(names((*value)[robot], where), where);
  }
  const std::string where = "parameter '" + param + "'";
  return CommandSources(names(*value, where), where);
}

bool accept(CommandSources& sources, const ros::MessageEvent<const ddace::WheelCommand>& ev, const std::string& node,
            const std::string& robot) {
  const std::string& publisher = ev.getPublisherName();
  switch (sources.check(publisher, !ev.getMessage()->header.stamp.isZero())) {
    case CommandSources::Verdict::Accepted:
      return true;
    case CommandSources::Verdict::Foreign:
      ROS_WARN_THROTTLE(1.0, "%s: /robots/%s/wheels: command from %s refused: not one of [%s] (foreign commands: %s)",
                        node.c_str(), robot.c_str(), publisher.c_str(), sources.allowedList().c_str(),
                        sources.foreignReport().c_str());
      return false;
    case CommandSources::Verdict::Unstamped:
      ROS_WARN_THROTTLE(1.0, "%s: /robots/%s/wheels: command from %s refused: its stamp is 0 (unstamped commands: %s)",
                        node.c_str(), robot.c_str(), publisher.c_str(), sources.unstampedReport().c_str());
      return false;
  }
  return false;
}

void diagnose(const CommandSources& sources, uint64_t& reported_foreign,
              diagnostic_updater::DiagnosticStatusWrapper& status) {
  status.add("command sources", sources.allowedList());
  status.add("foreign commands", sources.foreignReport());
  status.add("unstamped commands", sources.unstampedReport());
  // A node the launch did not name is publishing wheel commands right now: say so.
  if (sources.foreign() > reported_foreign)
    status.mergeSummary(diagnostic_msgs::DiagnosticStatus::WARN,
                        "wheel commands from " + sources.lastForeign() + " refused (not a command source)");
  reported_foreign = sources.foreign();
}

}  // namespace ddace::ros_command
