// Which nodes may command a robot's wheels, and a tally of the commands refused.
//
// A robot obeys the nodes its launch file names for it: its path follower, the
// coordinator (which zeroes the wheels when a node dies or the run stops) and a calibration
// tool when it runs. A command from any other publisher is refused, and so is an unstamped
// one (stamp 0 would skip the age check that stops a robot on stale commands). This is a
// safety interlock against stray nodes and mistakes, not authentication: the publisher's
// name is the caller id it announces, which any process can forge (docs/trust-boundary.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ddace {

class CommandSources {
 public:
  enum class Verdict { Accepted, Foreign, Unstamped };

  /// `allowed`: fully resolved node names ("/path_follower"); `where` names their origin in
  /// errors ("parameter '/hamster_bridge/command_sources'"). Throws ddace::Error when the
  /// list is empty or a name is not an absolute node name.
  CommandSources(std::vector<std::string> allowed, const std::string& where);

  /// Judges one command from `publisher`; counts a refusal and remembers who sent it.
  /// A foreign publisher counts as foreign whether or not its command is stamped.
  Verdict check(const std::string& publisher, bool stamped);

  const std::vector<std::string>& allowed() const { return allowed_; }
  /// "/path_follower, /coordinator"
  std::string allowedList() const;

  uint64_t foreign() const { return foreign_; }
  uint64_t unstamped() const { return unstamped_; }
  /// The last refused publisher of each kind ("" before the first).
  const std::string& lastForeign() const { return last_foreign_; }
  const std::string& lastUnstamped() const { return last_unstamped_; }

  /// "40, last from /intruder" (or "0"): the diagnostics' value of "foreign commands".
  std::string foreignReport() const;
  /// "3, last from /path_follower" (or "0"): the value of "unstamped commands".
  std::string unstampedReport() const;

 private:
  std::vector<std::string> allowed_;
  uint64_t foreign_ = 0, unstamped_ = 0;
  std::string last_foreign_, last_unstamped_;
};

}  // namespace ddace
