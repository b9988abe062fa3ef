#include "ddace/exec/liveness.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "ddace/common/error.h"

namespace ddace::exec {

size_t RoleWatch::add(const std::string& role, const std::string& node, const std::string& what,
                      double heartbeat_timeout_s) {
  if (node.empty()) throw Error("role '" + role + "' has no node");
  if (!(heartbeat_timeout_s >= 0) || !std::isfinite(heartbeat_timeout_s))
    throw Error("role '" + role + "': the heartbeat time-out must be >= 0");
  roles_.push_back({role, node, what, heartbeat_timeout_s});
  return roles_.size() - 1;
}

void RoleWatch::present(size_t role, bool present) {
  roles_.at(role).present = present;
}

void RoleWatch::heartbeat(size_t role, double now_s) {
  roles_.at(role).last_heartbeat_s = now_s;
}

void RoleWatch::arm(double now_s) {
  armed_ = true;
  armed_s_ = now_s;
}

std::vector<std::string> RoleWatch::missing() const {
  std::vector<std::string> out;
  for (const auto& r : roles_)
    if (!r.present) out.push_back(r.name + " (node " + r.node + ", " + r.what + ")");
  return out;
}

std::optional<std::string> RoleWatch::lost(double now_s) const {
  if (!armed_) return std::nullopt;
  for (const auto& r : roles_) {
    if (!r.present) return "lost the " + r.name + ": node " + r.node + " is gone (no longer " + r.what + ")";
    if (r.heartbeat_timeout_s > 0) {
      const double since = std::max(r.last_heartbeat_s, armed_s_);
      if (now_s - since > r.heartbeat_timeout_s) {
        std::ostringstream os;
        os << "lost the " << r.name << ": node " << r.node << " silent for " << now_s - since
           << " s (heartbeat time-out " << r.heartbeat_timeout_s << " s)";
        return os.str();
      }
    }
  }
  return std::nullopt;
}

}  // namespace ddace::exec
