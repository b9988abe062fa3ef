// Which node serves each role of a run, and whether it still does.
//
// A role (the sequence node, the path node, the follower of a robot, the pose source) is
// served by one named node. The caller reports what it sees on the wire: whether the node
// is connected on the role's topic (`present`) and when a message of the node last came
// (`heartbeat`). A role is lost when its node, once present, is no longer present, or when
// its heartbeat (for roles that have one) is older than the role's timeout.
//
// Owns: the roles, the rule. Must not: talk ROS, read clocks. Units: seconds.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace ddace::exec {

class RoleWatch {
 public:
  /// `heartbeat_timeout_s` = 0: presence only. Returns the role's index. `what` says on
  /// which topic the node serves it, for messages ("subscribed to /ddace/decision_request").
  size_t add(const std::string& role, const std::string& node, const std::string& what, double heartbeat_timeout_s = 0);

  void present(size_t role, bool present);
  void heartbeat(size_t role, double now_s);
  /// Starts the heartbeat clocks at `now_s` (a run begins): a node has its timeout to speak.
  void arm(double now_s);
  void disarm() { armed_ = false; }
  bool armed() const { return armed_; }

  /// Roles whose node is not present now, as "sequence (node /sequence, subscribed to ...)",
  /// empty when every role is served: the start check.
  std::vector<std::string> missing() const;
  /// The first lost role while armed, as a reason naming the node; nullopt while all serve.
  std::optional<std::string> lost(double now_s) const;

  size_t size() const { return roles_.size(); }
  const std::string& node(size_t role) const { return roles_[role].node; }

 private:
  struct Role {
    std::string name, node, what;
    double heartbeat_timeout_s = 0;
    bool present = false;
    double last_heartbeat_s = -1;
  };
  std::vector<Role> roles_;
  bool armed_ = false;
  double armed_s_ = 0;
};

}  // namespace ddace::exec
