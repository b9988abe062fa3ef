// The closed-loop simulator's execution model with bodies (`ddace eval --execution
// diffdrive`): every motion of a step runs at the same time on the simulated table of the
// mock robots (exec/table_simulator.h: Box2D discs of the task's footprints, objects
// carried along their own paths or riding with their carriers, pushed when something
// drives into them). Each robot runs exec::RobotController -- the very control cycle of
// path_follower_node (path following, safety filter, deadlocks, ended at contact) -- from
// its measured pose and the others'; what each motion may touch is decided once when the
// step begins from the step's end points (exec::motionContacts, the node's answer too).
// Without the filter (safety.enabled false) the bodies still collide, and every collision
// is counted. A load at its carrier rides in front of it during their step
// (TableSimulator::ride), part of the carrier's body for its filter.
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
// Owns: the step's control loop and its measurements. Must not: decide where motions end
// (task/end_point.h, via the planned paths) or score the trial (eval/metrics.h).
// Units: metres, radians, seconds; table frame.
#pragma once

#include <memory>
#include <set>
#include <utility>

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
  /// tolerance of noise_m), toward a body within task::stopRadiusToward.
  double arrival_radius_m = task::kDefaultArrivalRadius;
  double noise_m = 0;  ///< std-dev of measured x and y (the simulated Hamster's noise is replaced)
  uint64_t seed = 1;
};

/// Two bodies in contact have parted when their gap exceeds this (metres): Box2D keeps
/// resting bodies within a fraction of a millimetre of each other.
inline constexpr double kPartedM = 0.002;

class BodiesExecution : public ExecutionModel {
 public:
  /// Throws ddace::Error for invalid parameters, naming the first.
  explicit BodiesExecution(const BodiesExecutionParams& params);
  ~BodiesExecution() override;
  std::string name() const override { return params_.config.safety.enabled ? "bodies" : "bodies-unfiltered"; }
  bool bodies() const override { return true; }
  void beginTrial(const task::TaskSpec& spec, const std::vector<Pose2D>& start) override;
  StepExecution executeStep(const task::TaskSpec& spec, const std::vector<task::Token>& tokens,
                            const std::vector<Eigen::Vector2d>& positions,
                            const std::vector<StepMotion>& motions) override;
  BodyReport report() const override { return report_; }
  /// Not used: motions run together (executeStep). Throws ddace::Error.
  Path follow(const Path& planned, bool is_robot, int entity) override;

 private:
  struct Step;  // one step's motions while they run (bodies_execution.cpp)
  /// Where the step's bodies end, what each motion may touch, which loads ride.
  void decideContacts(Step& step);
  std::vector<BodyAtStart> bodiesAtStart(const Step& step) const;
  MotionContacts contactsOf(const Step& step, const std::vector<BodyAtStart>& bodies, int entity) const;
  std::string targetName(int target) const;  ///< "" for none
  static void dropLoad(MotionContacts& contacts);
  void rideLoad(Step& step, int carrier);
  /// Motion `m` starts: a robot's controller gets its path, an object its segment.
  void startMotion(Step& step, size_t m);
  void endRide(Step& step, int carrier, bool arrived);
  void cycleRobots(Step& step);
  void advanceTable(Step& step);
  void judgeContacts(Step& step);
  void stopUnfinished(Step& step);

  BodiesExecutionParams params_;
  ControllerParams controller_;
  double stop_tolerance_m_ = 0;  ///< task::stopTolerance of this model's noise
  double stop_radius_m_ = 0;     ///< task::stopRadius with it
  std::unique_ptr<TableSimulator> table_;
  std::vector<std::unique_ptr<RobotController>> controllers_;  ///< one per entity (robots only)
  std::vector<double> radius_m_;                               ///< every entity's body (0: a goal)
  std::vector<bool> robot_;
  std::vector<std::string> names_;
  size_t contacts_seen_ = 0;           ///< table_->contacts() already judged
  std::vector<PairContact> touching_;  ///< a * n + b (a < b): the run report's contact rule
  uint32_t next_segment_ = 1;
  uint64_t trials_ = 0;
  BodyReport report_;
};

}  // namespace ddace::exec
