#include "ddace/exec/liveness.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "ddace/common/error.h"

namespace ddace::exec {

RoleWatch::RoleWatch(double own_pause_s) : own_pause_s_(own_pause_s) {
  if (!(own_pause_s > 0) || !std::isfinite(own_pause_s)) throw Error("RoleWatch: own_pause_s must be positive");
}

size_t RoleWatch::add(const std::string& role, const std::string& node, const std::string& what,
                      double heartbeat_timeout_s) {
  if (node.empty()) throw Error("role '" + role + "' has no node");
  if (!(heartbeat_timeout_s >= 0) || !std::isfinite(heartbeat_timeout_s))
    throw Error("role '" + role + "': the heartbeat time-out must be >= 0");
  Role r;
  r.name = role;
  r.node = node;
  r.what = what;
  r.heartbeat_timeout_s = heartbeat_timeout_s;
  roles_.push_back(r);
  return roles_.size() - 1;
}

void RoleWatch::present(size_t role, bool present) {
  roles_.at(role).present = present;
}

void RoleWatch::heartbeat(size_t role, double now_s) {
  Role& r = roles_.at(role);
  if (armed_) r.longest_silence_s = std::max(r.longest_silence_s, silence(r, now_s));
  r.last_heartbeat_s = now_s;
}

void RoleWatch::fault(size_t role, const std::string& problem) {
  roles_.at(role).fault = problem;
}

void RoleWatch::arm(double now_s) {
  armed_ = true;
  listening_since_s_ = last_check_s_ = now_s;
  for (auto& r : roles_) r.longest_silence_s = 0;
}

double RoleWatch::silence(const Role& r, double now_s) const {
  return now_s - std::max(r.last_heartbeat_s, listening_since_s_);
}

std::vector<std::string> RoleWatch::missing(double now_s) const {
  std::vector<std::string> out;
  for (const auto& r : roles_) {
    if (!r.present) {
      out.push_back(r.name + " (node " + r.node + ", " + r.what + ")");
    } else if (!r.fault.empty()) {
      out.push_back(r.name + " (node " + r.node + ": " + r.fault + ")");
    } else if (r.heartbeat_timeout_s > 0 && r.last_heartbeat_s < 0) {
      out.push_back(r.name + " (node " + r.node + ": no heartbeat heard yet)");
    } else if (r.heartbeat_timeout_s > 0 && now_s - r.last_heartbeat_s > r.heartbeat_timeout_s) {
      std::ostringstream os;
      os << std::fixed << std::setprecision(2) << r.name << " (node " << r.node << ": silent for "
         << now_s - r.last_heartbeat_s << " s)";
      out.push_back(os.str());
    }
  }
  return out;
}

std::optional<std::string> RoleWatch::check(double now_s) {
  if (!armed_) return std::nullopt;
  // Our own pause: what came meanwhile may not have been handed to us yet.
  if (now_s - last_check_s_ > own_pause_s_) listening_since_s_ = now_s;
  last_check_s_ = now_s;
  for (auto& r : roles_) {
    if (!r.present) return "lost the " + r.name + ": node " + r.node + " is gone (no longer " + r.what + ")";
    if (!r.fault.empty()) return "lost the " + r.name + ": node " + r.node + " reports: " + r.fault;
    if (r.heartbeat_timeout_s > 0) {
      const double since = silence(r, now_s);
      r.longest_silence_s = std::max(r.longest_silence_s, since);
      if (since > r.heartbeat_timeout_s) {
        std::ostringstream os;
        os << "lost the " << r.name << ": node " << r.node << " silent for " << since << " s (heartbeat time-out "
           << r.heartbeat_timeout_s << " s)";
        return os.str();
      }
    }
  }
  return std::nullopt;
}

std::string RoleWatch::longestSilences() const {
  std::ostringstream os;
  os << std::fixed << std::setprecision(2);
  for (const auto& r : roles_) {
    if (r.heartbeat_timeout_s <= 0) continue;
    os << (os.tellp() > 0 ? ", " : "") << r.name << " " << r.longest_silence_s << " s of " << r.heartbeat_timeout_s
       << " s";
  }
  return os.str();
}

}  // namespace ddace::exec
