// The check every node runs once constructed (node_runner.h, nodelets.cpp): no parameter
// given under its private namespace left unread (params.h records what it read).
#include "params.h"

#include <algorithm>

#include "ddace/ros/node_runner.h"

namespace ddace::nodes {

std::vector<std::string> givenParams(const ros::NodeHandle& pnh) {
  std::vector<std::string> all, given;
  if (!ros::param::getParamNames(all)) throw Error("could not list the parameter server's parameters");
  for (const std::string& name : all)
    if (name.rfind(pnh.getNamespace() + "/", 0) == 0) given.push_back(name);
  return given;
}

void rejectUnknownParams(const ros::NodeHandle& pnh, const std::vector<std::string>& given) {
  std::vector<std::string> unknown;
  for (const std::string& name : given)
    if (!rosparam::ReadParams::known(name)) unknown.push_back(name);
  if (unknown.empty()) return;
  std::sort(unknown.begin(), unknown.end());
  const std::string ns = pnh.getNamespace();
  std::string list, known;
  for (const std::string& u : unknown) list += (list.empty() ? "" : ", ") + u;
  for (const std::string& k : rosparam::ReadParams::under(ns)) known += (known.empty() ? "" : ", ") + k;
  throw Error(std::string(unknown.size() == 1 ? "parameter " : "parameters ") + list +
              (unknown.size() == 1 ? " is" : " are") + " not one of node " + ns +
              "'s (a typo, or a parameter of another node, would leave it on its default); its parameters: " + known);
}

}  // namespace ddace::nodes
