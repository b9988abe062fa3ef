// What roslaunch's own loader makes of this repository's launch files, nothing started:
// their nodes (arguments, required, network mode) and parameters, or why the loader
// refused a file. The one copy for the tests of launch files.
#pragma once

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "ddace/common/repository.h"
#include "run_tool.h"

namespace ddace::test {

/// A node as the loader sees it.
struct LaunchNode {
  std::string name, args;
  bool required = false;
  std::string network;  ///< its DDACE_NETWORK ("" when unset)
};

/// A launch file as the loader sees it.
struct LaunchConfig {
  std::string refused;                        ///< why the loader stopped; "" when it loaded
  std::vector<LaunchNode> nodes;              ///< every node, in the file's order
  std::map<std::string, std::string> params;  ///< name -> value as Python prints it
  /// The node called `name`, or nullptr.
  const LaunchNode* node(const std::string& name) const {
    for (const auto& n : nodes)
      if (n.name == name) return &n;
    return nullptr;
  }
};

/// True when this user can make user and network namespaces (loadLaunches needs them).
inline bool namespacesWork() {
  return std::system("unshare --map-root-user --net -- true >/dev/null 2>&1") == 0;
}

/// Shell text that gives the network namespace it runs in an interface besides loopback,
/// standing for the host's network (a bridge, a veth pair or a tap: whatever this kernel has).
inline const char* const kAddInterface =
    "(ip link add eth9 type bridge || ip link add eth9 type veth peer name eth8 || ip tuntap add dev eth9 mode tap)";

/// Loads each of `files` (names in this repository's launch/) with `args` (ARG:=VALUE ...,
/// shell text) by roslaunch's loader, in a network namespace of its own with only
/// loopback, or with `hostNetwork` one more interface, as on a host. `$(find ddace)` is
/// this repository. The loader's own output goes to `out` when given.
inline std::map<std::string, LaunchConfig> loadLaunches(const std::vector<std::string>& files, const std::string& args,
                                                        bool hostNetwork = false, std::string* out = nullptr) {
  const std::filesystem::path repo = findRepository("", {"launch/record.launch"});
  const std::string loader = ::testing::TempDir() + "launch_loader.py";
  // One line a fact, fields split by tabs: FILE refused WHY | FILE node NAME REQUIRED
  // DDACE_NETWORK ARGS | FILE param NAME VALUE.
  std::ofstream(loader)
      << "import sys, roslaunch.config as c\n"
         "flat = lambda v: str(v).replace(chr(10), ' ').replace(chr(9), ' ')\n"
         "for f in sys.argv[2:]:\n"
         "  name = f.split('/')[-1]\n"
         "  try:\n"
         "    cfg = c.load_config_default([(f, sys.argv[1].split())], None)\n"
         "  except Exception as e:\n"
         "    print(name, 'refused', flat(e), sep=chr(9))\n"
         "    continue\n"
         "  for n in cfg.nodes:\n"
         "    print(name, 'node', n.name, n.required, dict(n.env_args).get('DDACE_NETWORK', ''), n.args, sep=chr(9))\n"
         "  for k, p in cfg.params.items():\n"
         "    print(name, 'param', k, flat(p.value), sep=chr(9))\n";
  std::string cmd = "ip link set lo up && " + std::string(hostNetwork ? kAddInterface : "true") +
                    " && ROS_PACKAGE_PATH='" + repo.string() + "':\\\"$ROS_PACKAGE_PATH\\\" /usr/bin/python3 '" +
                    loader + "' '" + args + "'";
  for (const auto& f : files) cmd += " '" + (repo / "launch" / f).string() + "'";
  const ToolRun r = runShell("unshare --map-root-user --net -- /bin/sh -c \"" + cmd + "\"");
  if (out) *out = r.out;
  std::map<std::string, LaunchConfig> configs;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    std::vector<std::string> f;
    std::istringstream fields(line);
    for (std::string s; std::getline(fields, s, '\t');) f.push_back(s);
    if (f.size() == 3 && f[1] == "refused") configs[f[0]].refused = f[2];
    if (f.size() >= 5 && f[1] == "node")
      configs[f[0]].nodes.push_back({f[2], f.size() > 5 ? f[5] : "", f[3] == "True", f[4]});
    if (f.size() >= 3 && f[1] == "param") configs[f[0]].params[f[2]] = f.size() > 3 ? f[3] : "";
  }
  return configs;
}

}  // namespace ddace::test
