// networkAsLaunched: see include/ddace/ros/node_runner.h.
#include "ddace/ros/node_runner.h"

#include <net/if.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace ddace::nodes {

bool networkAsLaunched(const char* default_name) {
  const char* mode = std::getenv("DDACE_NETWORK");
  if (mode == nullptr || std::string(mode) != "loopback") return true;
  std::string others;
  if (struct if_nameindex* ifs = if_nameindex()) {
    for (struct if_nameindex* i = ifs; i->if_index != 0; ++i)
      if (std::string(i->if_name) != "lo") others += (others.empty() ? "" : ", ") + std::string(i->if_name);
    if_freenameindex(ifs);
  }
  if (others.empty()) return true;
  std::fprintf(stderr,
               "%s: not started: the launch asked for one machine (lab_network:=false), but this process runs on the "
               "host's network (%s), where its XML-RPC port would listen on every interface: start the launch in "
               "scripts/loopback_only (network_mode says how)\n",
               default_name, others.c_str());
  return false;
}

}  // namespace ddace::nodes
