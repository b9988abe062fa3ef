// scripts/network_mode.py, the network-mode check of the launch files, run in network
// namespaces this test makes (unshare --map-root-user --net): only loopback, plus a private
// lab address put on it. No traffic leaves them. And every launch file that starts a graph
// runs it, one machine by default, and refuses to load on a network with more than loopback.
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "ddace/common/repository.h"
#include "launch_config.h"
#include "run_tool.h"

namespace {

using ddace::test::kAddInterface;
using ddace::test::namespacesWork;
using ddace::test::runShell;
using ddace::test::ToolRun;

/// scripts/NAME of this repository.
std::string script(const std::string& name) {
  return (ddace::findRepository("", {"scripts/" + name}) / "scripts" / name).string();
}

/// Runs `env` + network_mode.py `args` --check-only in a new network namespace whose
/// loopback is up and also holds 10.9.9.9 (a private address of "this host").
ToolRun inNamespace(const std::string& env, const std::string& args) {
  const std::string inner = "ip link set lo up && ip addr add 10.9.9.9/32 dev lo && env -u ROS_HOSTNAME -u ROS_IP " +
                            env + " /usr/bin/python3 '" + script("network_mode.py") + "' " + args + " --check-only";
  return runShell("unshare --map-root-user --net -- /bin/sh -c \"" + inner + "\"");
}

}  // namespace

TEST(NetworkMode, OneMachineModePassesInALoopbackOnlyNamespace) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  const ToolRun r = inNamespace("", "--lab-network false");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("only loopback"), std::string::npos) << r.out;
}

TEST(NetworkMode, LabModeNeedsROS_IPOnAPrivateAddressOfThisHostAndSaysWhatIsExposed) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  ToolRun r = inNamespace("ROS_IP=10.9.9.9 ROS_MASTER_URI=http://10.9.9.9:11311", "--lab-network true");
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("reachable from other hosts through lo (10.9.9.9)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("exposed:"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ip saddr != {"), std::string::npos) << "no firewall rule:\n" << r.out;

  r = inNamespace("", "--lab-network true");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("needs ROS_IP"), std::string::npos) << r.out;
  r = inNamespace("ROS_IP=127.0.0.1", "--lab-network true");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("is loopback"), std::string::npos) << r.out;
  r = inNamespace("ROS_IP=8.8.8.8", "--lab-network true");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("not a private address"), std::string::npos) << r.out;
  r = inNamespace("ROS_IP=10.9.9.8", "--lab-network true");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("is no address of this host"), std::string::npos) << r.out;
  r = inNamespace("ROS_IP=10.9.9.9 ROS_HOSTNAME=localhost", "--lab-network true");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("unset ROS_HOSTNAME"), std::string::npos) << r.out;
}

/// The arguments of every network_mode node of each launch file in `files` with
/// task:=t model:=m `extra`, and the DDACE_NETWORK its nodes get: one line "FILE: [args,
/// ...] [modes...]" per file, or "FILE: refused: WHY" when the loader stops; then the
/// loader's own output. On a network with only loopback, or with `hostNetwork` as on a host.
static std::string networkModeArgs(const std::vector<std::string>& files, const std::string& extra,
                                   bool hostNetwork = false) {
  std::string loader;
  const auto configs = ddace::test::loadLaunches(files, "task:=t model:=m " + extra, hostNetwork, &loader);
  std::string out;
  for (const auto& [file, config] : configs) {
    if (!config.refused.empty()) {
      out += file + ": refused: " + config.refused + "\n";
      continue;
    }
    std::vector<std::string> args;
    std::set<std::string> modes;
    for (const auto& n : config.nodes) {
      if (n.name.rfind("network_mode", 0) == 0) args.push_back("'" + n.args + "'");
      modes.insert("'" + n.network + "'");
    }
    auto list = [](const auto& items) {
      std::string l;
      for (const auto& i : items) l += (l.empty() ? "" : ", ") + i;
      return "[" + l + "]";
    };
    out += file + ": " + list(args) + " " + list(modes) + "\n";
  }
  return out + loader;
}

TEST(NetworkMode, EveryLaunchFileThatStartsAGraphStatesItsMode) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  const std::vector<std::string> files{"record.launch", "tabletop.launch", "execute_real.launch"};
  // One check each: execute_real.launch includes tabletop.launch and turns its check off.
  std::string out = networkModeArgs(files, "");
  for (const auto& f : files)
    EXPECT_NE(out.find(f + ": ['--lab-network false --launch " + f + "'] ['loopback']"), std::string::npos)
        << f << ": one machine is the default\n"
        << out;
  out = networkModeArgs(files, "lab_network:=true");
  for (const auto& f : files)
    EXPECT_NE(out.find(f + ": ['--lab-network true --launch " + f + "'] ['lab']"), std::string::npos)
        << f << ": lab_network:=true\n"
        << out;
}

TEST(NetworkMode, AOneMachineLaunchOnAHostsNetworkIsRefusedBeforeRoslaunchOpensAPort) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  // roslaunch loads the whole file before it starts its XML-RPC server or a master: refused
  // by the loader, a launch has listened on nothing. What counts is the network the loader
  // is on (its interfaces), nothing a user could set.
  const std::string dir = (ddace::findRepository("", {"launch/record.launch"}) / "launch").string();
  const std::vector<std::string> files{"record.launch", "tabletop.launch", "execute_real.launch", "execute_sim.launch"};
  std::string out = networkModeArgs(files, "", true);
  for (const auto& f : files) {
    EXPECT_NE(out.find(f + ": refused: while processing " + dir + "/one_machine.xml"), std::string::npos)
        << f << " on a network with more than loopback\n"
        << out;
    EXPECT_NE(out.find("refused: " + f +
                       " runs on one machine (lab_network:=false), but this process is on a network "
                       "with more than loopback: interfaces lo, eth"),
              std::string::npos)
        << f << ": the message names what is exposed\n"
        << out;
    EXPECT_NE(out.find("  scripts/loopback_only roslaunch ddace " + f + " ..."), std::string::npos)
        << f << ": the message says how to start it\n"
        << out;
  }
  // A multi-machine lab is asked for on purpose: no namespace.
  const std::vector<std::string> lab{"record.launch", "tabletop.launch", "execute_real.launch"};
  out = networkModeArgs(lab, "lab_network:=true", true);
  for (const auto& f : lab)
    EXPECT_NE(out.find(f + ": ['--lab-network true --launch " + f + "'] ['lab']"), std::string::npos)
        << f << ": lab_network:=true loads without a namespace\n"
        << out;
}

TEST(NetworkMode, JoinRunsACommandInTheNamespaceOfARunningGraph) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  // A graph in a namespace of its own (the target prints its namespace, then waits), and
  // `loopback_only --join PID` from outside: the command must run in the target's namespace.
  const std::string shell = ::testing::TempDir() + "join_check.sh";
  std::ofstream(shell)
      << "f=$(mktemp)\n"
         "unshare --map-root-user --net -- sh -c \"readlink /proc/self/ns/net > $f; exec sleep 30\" &\n"
         "p=$!\n"
         "for i in $(seq 100); do [ -s $f ] && break; sleep 0.1; done\n"
         "echo target $(cat $f)\n"
         "echo own $(readlink /proc/self/ns/net)\n"
         "echo joined $(\"$1\" --join $p readlink /proc/self/ns/net)\n"
         "kill $p; rm -f $f\n";
  const std::string out = runShell("/bin/bash '" + shell + "' '" + script("loopback_only") + "'").out;
  auto field = [&](const std::string& key) {
    const size_t at = out.find(key + " ");
    return at == std::string::npos ? std::string()
                                   : out.substr(at + key.size() + 1, out.find('\n', at) - at - key.size() - 1);
  };
  ASSERT_NE(field("target"), "") << out;
  EXPECT_EQ(field("joined"), field("target")) << out;
  EXPECT_NE(field("joined"), field("own")) << out;
}

TEST(NetworkMode, JoinWithoutAPidRefusesWhenMoreThanOneGraphRunsListingThem) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  // Two "graphs": a program called roslaunch in each of two namespaces. Other graphs of this
  // user may run too (listed as well): what counts is that none is joined and both are named.
  const std::string dir = ::testing::TempDir() + "join_two";
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/roslaunch") << "trap 'kill $s; exit 0' TERM\nreadlink /proc/self/ns/net > $1.ready\n"
                                       "sleep 30 & s=$!\nwait $s\n";
  std::ofstream(dir + "/check.sh")
      << "d=$2; rm -f $d/a.ready $d/b.ready\n"
         "unshare --map-root-user --net -- /bin/sh $d/roslaunch $d/a ddace first.launch & a=$!\n"
         "unshare --map-root-user --net -- /bin/sh $d/roslaunch $d/b ddace second.launch & b=$!\n"
         "for i in $(seq 200); do [ -s $d/a.ready ] && [ -s $d/b.ready ] && break; sleep 0.1; done\n"
         "echo pids $a $b\n"
         "\"$1\" --join readlink /proc/self/ns/net; echo status $?\n"
         "kill $a $b; wait\n";
  const ToolRun r = runShell("/bin/bash '" + dir + "/check.sh' '" + script("loopback_only") + "' '" + dir + "'");
  const size_t at = r.out.find("pids ");
  ASSERT_NE(at, std::string::npos) << r.out;
  std::string a, b;
  std::istringstream(r.out.substr(at + 5)) >> a >> b;
  EXPECT_NE(r.out.find("status 2"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("net:["), std::string::npos) << "joined a graph:\n" << r.out;
  EXPECT_NE(r.out.find("give the PID of the one to join"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PID " + a + ", started "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PID " + b + ", started "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("roslaunch " + dir + "/a ddace first.launch"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("roslaunch " + dir + "/b ddace second.launch"), std::string::npos) << r.out;
}

TEST(NetworkMode, ANodeOfAOneMachineLaunchRefusesToOpenAPortOnTheHostsNetwork) {
  if (!namespacesWork()) GTEST_SKIP() << "no user and network namespaces here (docs/trust-boundary.md)";
  // A namespace with an interface besides loopback stands for the host's network; no master
  // is running: the node must stop before it opens anything (before ros::init).
  const std::string node =
      (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "path_follower_node").string();
  ASSERT_TRUE(std::filesystem::exists(node)) << node;
  const ToolRun r =
      runShell("unshare --map-root-user --net -- /bin/sh -c \"ip link set lo up && " + std::string(kAddInterface) +
               " && DDACE_NETWORK=loopback ROS_MASTER_URI=http://127.0.0.1:1 '" + node + "'\"");
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("not started: the launch asked for one machine"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("eth9"), std::string::npos) << r.out;
}
