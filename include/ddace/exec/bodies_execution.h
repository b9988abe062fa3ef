// The closed-loop simulator's execution model with bodies (`ddace eval --execution
// diffdrive`): every motion of a step runs at the same time on the simulated table of the
// mock robots (exec/table_simulator.h: Box2D discs of the task's footprints, objects
// carried along their own paths or going with their carriers, pushed when something
// drives into them). Each robot runs exec::RobotController -- the very control cycle of
// path_follower_node (path following, safety filter, deadlocks, ended at contact) -- from
// its measured pose and the others'; what each motion may touch is decided once when the
// step begins from the step's end points (exec::motionContacts, the node's answer too).
// Without the filter (safety.enabled false) the bodies still collide, and every collision
// is counted. A load at its carrier goes with it during their step (TableSimulator::carry):
// by default the carrier pushes it as on the real table (exec/push_path.h), and the load is
// judged where it lies when its carrier is done; with mock_robots/loads_ride true (`ddace
// eval --config`) it rides in front of it, part of the carrier's body for its filter.
//
// A step ends when every robot's control law reports it arrived and every object's segment
// is done, or when its filter reports a deadlock (the robot stops there; the failure names
// it), or at the time limit (3x the longest path at cruise speed + 10 s, as the model
// without bodies). Collisions: two bodies apart that touch (a Box2D contact begins), except
// the pairs allowed to touch in the step (exec::AllowedContacts: what the step's motions
// may touch, as given to their controllers -- a motion and its own target, a carrier and the
// load riding with it, a motion and a body its end point touches while that body is at the
// end point); a pair that touched while allowed (a motion that ended at its target) counts
// again after it parted (kPartedM), or when, no longer allowed, it overlaps deeper than
// kPartedM (exec::PairContact, the run report's rule), so a robot leaving a neighbour it
// touches is no collision; bodies placed overlapping at the start never collide. The closest approach is measured on
// the true poses every cycle over the pairs that are apart, with the same exceptions.
//
// A live run (the coordinator's dispatch, pipeline/perturbation.h) starts motions whenever
// they are sent (startMotions), while others run, and advances the table one control cycle
// at a time (cycle()); executeStep is one batch started and run to its end. What a motion
// may touch is then decided from where every running motion ends, whatever its step (as
// the path follower node decides it from the segments it knows). A hand may nudge a body,
// stall a robot's wheels or kill a robot (displace, stall, kill).
//
// Owns: the control loop of the running motions and its measurements. Must not: decide where motions end
// (task/end_point.h, via the planned paths) or score the trial (eval/metrics.h).
// Units: metres, radians, seconds; table frame.
#pragma once

#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "ddace/exec/clearance.h"
#include "ddace/exec/execution_config.h"
#include "ddace/exec/robot_controller.h"
#include "ddace/exec/simulator.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/task/end_point.h"

namespace ddace::exec {

struct BodiesExecutionParams {
  ExecutionConfig config;  ///< the robots' controller, the simulated Hamster, the table (bodies)
  /// The task's; each motion stops within task::stopRadius of its end point (with the stop
  /// tolerance of noise_m), against a body within task::stopRadiusAgainstBody.
  double arrival_radius_m = task::kDefaultArrivalRadius;
  double noise_m = 0;  ///< std-dev of measured x and y (the simulated Hamster's noise is replaced)
  uint64_t seed = 1;
  /// The number of the first trial (then counting up): trial k's noise is drawn from seed and
  /// k, so a trial run alone (a coordinated run, one execution per trial) can draw the noise
  /// of the k-th trial of a run of many.
  uint64_t first_trial = 1;
};

/// Two bodies in contact have parted when their gap exceeds this (metres): Box2D keeps
/// resting bodies within a fraction of a millimetre of each other.
inline constexpr double kPartedM = 0.002;

/// A motion of a live run that ended (BodiesExecution::cycle).
struct MotionEnd {
  int entity = -1;
  bool done = false;        ///< arrived; else failed (a deadlock, its time limit), stopped where it is
  std::string message;      ///< why it failed, naming the robot; "ended at contact with X" when done there
  bool time_limit = false;  ///< stopped past its time limit
};

class BodiesExecution : public ExecutionModel {
 public:
  /// Throws ddace::Error for invalid parameters, naming the first.
  explicit BodiesExecution(const BodiesExecutionParams& params);
  ~BodiesExecution() override;
  std::string name() const override { return params_.config.safety.enabled ? "bodies" : "bodies-unfiltered"; }
  bool bodies() const override { return true; }
  bool pushesLoads() const override { return !params_.config.table.loads_ride; }
  void beginTrial(const task::TaskSpec& spec, const std::vector<Pose2D>& start) override;
  /// The step's motions start together (startMotions) and run until each ended or the
  /// step's time limit.
  StepExecution executeStep(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                            const std::vector<Eigen::Vector2d>& positions,
                            const std::vector<StepMotion>& motions) override;
  BodyReport report() const override { return report_; }
  /// Not used: motions run together (executeStep). Throws ddace::Error.
  Path follow(const Path& planned, bool is_robot, int entity) override;

  // A live run (the coordinator's dispatch): motions start whenever they are sent, while
  // others run, and the table advances one control cycle at a time.

  /// `motions` of step `step` (`tokens`: that step's) start together now, each replacing
  /// its entity's running motion. What each may touch is decided here from where every
  /// body is and where every running motion ends (the path follower's answer when segments
  /// of several steps run). Their time limit: the longest one's (3x its path at cruise
  /// speed + 10 s). Returns why motions could not start (a goal cannot move, a refused
  /// segment): those end at once. Throws ddace::Error before beginTrial.
  std::vector<std::string> startMotions(const task::TaskSpec& spec, int step, const std::vector<task::Token>& tokens,
                                        const std::vector<StepMotion>& motions);
  /// One control cycle of every robot and one period of the table; returns the motions that
  /// ended in it (arrived, failed, or past their time limit: stopped where they are).
  std::vector<MotionEnd> cycle();
  /// `entity`'s motion is cancelled: it stops where it is (no end reported).
  void stopMotion(int entity);
  bool moving(int entity) const;
  /// The positions `entity`'s latest motion passed through (empty: none).
  const Path& executed(int entity) const;
  double time() const;
  /// Every entity's true position.
  std::vector<Eigen::Vector2d> positions() const;

  // What happens to a table under a run (`ddace eval --perturb`).

  /// A hand puts `entity` down `by` metres away.
  void displace(int entity, const Eigen::Vector2d& by);
  /// Robot `entity`'s wheels do not turn until `until_s` (table time) whatever it commands.
  void stall(int entity, double until_s);
  /// Robot `entity` is dead (battery): its wheels never turn again and the tracker no longer
  /// sees it; its controller gets a stale pose.
  void kill(int entity);
  /// Robot `entity` drives at `factor` (> 0) of the speed it commands, for the rest of the
  /// trial: robots that differ in speed.
  void setSpeedFactor(int entity, double factor);

 private:
  struct Motion;  // one motion of the trial (bodies_execution.cpp)
  /// What motion `m` may touch, from every body's position and where each running motion ends.
  MotionContacts contactsOf(const Motion& m) const;
  std::string targetName(int target) const;  ///< "" for none
  static void dropLoad(MotionContacts& contacts);
  void rideLoad(int carrier);
  /// Motion `m` starts: a robot's controller gets its path, an object its segment. Returns
  /// why it cannot ("": it runs).
  std::string startMotion(size_t m);
  /// startMotions' parts, in order: the motions added (returns the index of the first),
  /// what the new ones may touch, the step's running robots told again, every new one
  /// started (the failures; one time limit for the batch), the contact rule for judging.
  size_t addMotions(int step, const std::vector<task::Token>& tokens, const std::vector<StepMotion>& motions);
  void decideNewContacts(size_t first);
  void redecideRunning(size_t first, int step);
  std::vector<std::string> launch(size_t first);
  void allowContacts(size_t first);
  void finish(size_t m);
  bool standing(int entity) const;
  void endRide(int carrier, bool arrived);
  void cycleRobots();
  void advanceTable();
  void judgeContacts();
  /// Motions of `batch` still moving stop where they are, past their time limit.
  void stopBatch(uint32_t batch);

  BodiesExecutionParams params_;
  ControllerParams controller_;
  double stop_tolerance_m_ = 0;  ///< task::stopTolerance of this model's noise
  double stop_radius_m_ = 0;     ///< task::stopRadius with it
  std::unique_ptr<TableSimulator> table_;
  std::vector<std::unique_ptr<RobotController>> controllers_;  ///< one per entity (robots only)
  std::vector<double> radius_m_;                               ///< every entity's body (0: a goal)
  std::vector<bool> robot_;
  std::vector<std::string> names_;
  task::TaskSpec spec_;
  std::vector<Motion> motions_;           ///< every motion of the trial, in start order
  std::vector<int> motion_of_;            ///< per entity: its latest motion, or -1
  std::vector<int> load_of_;              ///< per carrier: the load riding with it, or -1
  std::vector<double> stalled_until_s_;   ///< per robot: wheels blocked until then
  std::vector<bool> dead_;                ///< per robot: kill()ed
  std::set<std::pair<int, int>> loaded_;  ///< pairs placed overlapping (never judged)
  AllowedContacts allowed_;               ///< of the running motions, as of the last start
  std::vector<MotionEnd> ended_;          ///< since the last cycle()
  uint32_t batches_ = 0;
  int running_ = 0;                    ///< motions still moving
  size_t contacts_seen_ = 0;           ///< table_->contacts() already judged
  std::vector<PairContact> touching_;  ///< a * n + b (a < b): the run report's contact rule
  uint32_t next_segment_ = 1;
  uint64_t trials_ = 0;
  BodyReport report_;
  // Scratch of every cycle.
  std::vector<Pose2D> measured_;
  std::set<std::pair<int, int>> began_;
  std::vector<SafetyBody> others_;
};

}  // namespace ddace::exec
