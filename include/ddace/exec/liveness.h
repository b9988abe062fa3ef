// Which node serves each role of a run, and whether it still does.
//
// A role (the sequence node, the path node, the follower of a robot, the pose source, the
// recorder) is served by one named node. The caller reports what it sees on the wire:
// whether the node is connected on the role's topic (`present`), when a message of the node
// last came (`heartbeat`), and a problem the node itself reports (`fault`). A role is lost
// when its node, once present, is no longer present, when it reports a problem, or when its
// heartbeat (for roles that have one) is older than the role's time-out.
//
// Silence is counted only while the watcher itself was listening: a check that comes more
// than `own_pause_s` after the previous one means the watcher's own process did not run (a
// loaded machine), heartbeats that came meanwhile may still wait in its queue, and every
// heartbeat clock restarts at that check instead of blaming a node for the watcher's pause.
// So a node that stops at time t is lost at the first check after
// t + heartbeat time-out (+ any pause of the watcher longer than own_pause_s).
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
  /// `own_pause_s` > 0: see the file comment. Throws ddace::Error otherwise.
  explicit RoleWatch(double own_pause_s = 0.25);

  /// `heartbeat_timeout_s` = 0: presence only. Returns the role's index. `what` says on
  /// which topic the node serves it, for messages ("subscribed to /ddace/decision_request").
  size_t add(const std::string& role, const std::string& node, const std::string& what, double heartbeat_timeout_s = 0);

  void present(size_t role, bool present);
  void heartbeat(size_t role, double now_s);
  /// What the node says keeps it from serving its role ("rosbag record exited"); "" when
  /// nothing does. A fault counts as missing for the start check and as lost while armed.
  void fault(size_t role, const std::string& problem);
  /// Starts the heartbeat clocks at `now_s` (a run begins): a node has its timeout to speak.
  void arm(double now_s);
  void disarm() { armed_ = false; }
  bool armed() const { return armed_; }

  /// Roles whose node is not present now, reports a fault, or (for a role with a heartbeat)
  /// has not been heard within its time-out before `now_s`, as "sequence (node /sequence,
  /// subscribed to ...)"; empty when every role is served: the start check. A run starts
  /// only once every heartbeat is heard: a heartbeat whose link is still being set up when
  /// the run starts would otherwise count as silence.
  std::vector<std::string> missing(double now_s) const;
  /// One check at `now_s`: the first lost role while armed, as a reason naming the node;
  /// nullopt while all serve (and while disarmed).
  std::optional<std::string> check(double now_s);

  /// The longest silence of each heartbeat role since the last arm, against its time-out:
  /// "follower of R1 0.06 s of 1 s, ..." (how close a run came to losing a role).
  std::string longestSilences() const;

  size_t size() const { return roles_.size(); }
  const std::string& node(size_t role) const { return roles_[role].node; }

 private:
  struct Role {
    std::string name, node, what;
    double heartbeat_timeout_s = 0;
    bool present = false;
    std::string fault;
    double last_heartbeat_s = -1;
    double longest_silence_s = 0;
  };
  /// Seconds the role has been silent at `now_s`, counted while listening.
  double silence(const Role& r, double now_s) const;

  std::vector<Role> roles_;
  double own_pause_s_;
  bool armed_ = false;
  double listening_since_s_ = 0;  ///< the arm, or the last check after a pause of our own
  double last_check_s_ = 0;
};

}  // namespace ddace::exec
