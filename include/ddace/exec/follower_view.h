// What a path follower knows of the table and of the running step, beyond the robots it
// drives: every tracked body, and the segment of every entity -- its own robots' and those
// driven elsewhere (objects, other followers' robots) -- with where it ends. From these it
// decides, for a robot of its own, the stop radius toward its target
// (task::stopRadiusAgainstBody) and what its motion may touch
// (exec::motionContacts, from where the step's bodies end), and lists the other bodies for
// its controller, each marked standing or not. path_follower_node converts messages to and
// from these; its robots' control cycles are exec::RobotController's.
//
// A step's segments arrive one by one within milliseconds: a robot decides again what its
// motion may touch whenever its step's segments change (stepVersion()).
//
// Owns: the tracked bodies and the step's segments as the follower sees them. Must not:
// know ROS, read a clock (times come in), or drive anything.
// Units: metres, seconds; table frame.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/motion_contacts.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

class FollowerView {
 public:
  /// `kinds`: the task's entities by name (empty: none known; a tracked body of unknown
  /// kind is then kept off as an object); `arrival_radius_m`: the task's; `reach_m`: the
  /// safety filter's SafetyParams::endsAgainstReachM().
  FollowerView(std::map<std::string, task::Entity> kinds, double arrival_radius_m, double reach_m);

  /// A body as tracked at `seen_s`: `kind` as the tracker names it (the task's kind wins),
  /// `position` (non-finite: unknown), `stale` as the tracker flags it. Entities without a
  /// body (goals) are not kept.
  void track(const std::string& name, std::optional<task::EntityKind> kind, const Eigen::Vector2d& position, bool stale,
             double seen_s);

  /// The robots the coordinator lost for good (CoordinatorState::lost; names of no robot of
  /// the task are ignored and returned): each stays a standing body where it was last seen,
  /// its pose no longer stale -- a dead robot is an obstacle, not a reason to stop every
  /// robot that comes near it. Replaces the earlier list (empty: none).
  std::vector<std::string> setLost(const std::vector<std::string>& names);

  /// Entity `name`'s segment `id` of `step` (`action`, `target`) ending at `end`, along
  /// `way` (its planned path; empty: unknown): it replaces the last one, unless that id was
  /// reported ended already (another connection). Returns whether it was noted.
  bool noteSegment(const std::string& name, uint32_t id, int step, const std::string& action, const std::string& target,
                   const Eigen::Vector2d& end, std::vector<Eigen::Vector2d> way = {});
  /// Segment `id` of `name` ended (done, failed, aborted): forgotten.
  void noteEnded(const std::string& name, uint32_t id);
  /// Forgets `name`'s segment, whatever its id (a stop, a malformed segment).
  void forget(const std::string& name);
  /// Changes whenever a segment of `step` is noted or forgotten (the carrier of a load that
  /// ended decides again too).
  uint64_t stepVersion(int step) const;

  /// The stop radius of robot `robot`'s motion of `step` (`action` toward `target`), from
  /// `stop` (task::stopRadius): toward a tracked body, task::stopRadiusAgainstBody; onto a
  /// goal, or carrying a load (an object's segment of the step with the same action and
  /// target, known now: the load is what ends at the target), `stop`.
  double stopToward(const std::string& robot, int step, const std::string& action, const std::string& target,
                    double stop) const;
  /// The stop radius of a motion ending at its own place, within the stop tolerance, from
  /// `stop` (task::stopRadiusAgainstBody): toward a body, or awaited by a robot queued
  /// behind it (exec::RobotController::start).
  double stopAtPlace(double stop) const;
  /// What robot `robot`'s segment may touch (exec::motionContacts), it standing at
  /// `position` now, from where every body of the step ends.
  MotionContacts contacts(const std::string& robot, const Eigen::Vector2d& position) const;
  /// Every tracked body but `robot`, as its controller takes them at `now_s` (age, and
  /// standing: no segment running); `self_age_s`: how old `robot`'s own pose is (a very
  /// large number when stale or untracked).
  const std::vector<SafetyBody>& others(const std::string& robot, double now_s, double& self_age_s);
  /// A body's radius: as tracked, else a Hamster's.
  double radiusOf(const std::string& name) const;

 private:
  struct Segment {
    uint32_t id = 0;
    int step = -1;
    std::string action, target;
    Eigen::Vector2d end{0, 0};
    std::vector<Eigen::Vector2d> way;  ///< its planned path (empty: unknown)
  };
  struct Tracked {
    SafetyBody body;
    double seen_s = 0;
    bool known = false;  ///< a finite position was seen
  };
  bool isObject(const std::string& name) const;
  void bump(int step);

  std::map<std::string, task::Entity> kinds_;
  double arrival_m_, reach_m_;
  std::map<std::string, Tracked> bodies_;
  std::map<std::string, Segment> segments_;
  std::map<std::string, uint32_t> ended_;  ///< the last segment id reported ended, by name
  std::set<std::string> lost_;             ///< robots lost for good (setLost)
  std::map<int, uint64_t> versions_;
  std::vector<SafetyBody> others_;  ///< others()' answer
};

}  // namespace ddace::exec
