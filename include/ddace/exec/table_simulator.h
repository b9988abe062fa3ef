// The simulated table of the mock robot node: every entity of a task in time steps of
// 1/rate_hz, with bodies. Robots are exec::DiffDriveModel unicycles driven by wheel
// commands; objects move through their own segments, carried along the planned path at a
// constant speed (exec/scene.h's CarriedObject, the execution model of
// docs/task-format.md), and when something pushes them; goals are flat and never move. The
// load of a carry step goes with its carrier (carry()): riding in front of it (loads_ride,
// the mock robots' default) or pushed by it body against body, as on the real table.
//
// Bodies (params.bodies): every robot and object is a disc (exec/safety_filter.h's
// bodyShape) in a Box2D 2.4 world seen from above (no gravity). Each step a robot's unicycle decides where its
// wheels would take it; that motion becomes the body's velocity, Box2D resolves the
// contacts, and the robot ends where its body ends. Objects slide to rest by table
// friction (object_damping_hz) after a push. Every contact that begins is recorded
// (contacts()) and the closest approach of any two bodies kept (closestApproach()). Two
// bodies placed one on the other at the start (a load on its carrier, overlapping deeper
// than exec::kPlacedOnM) do not collide with each other and are not measured
// (loadedPairs()); two that touch at the start collide as any two, and no contact begins
// for them until they have parted.
//
// Owns: the poses, the bodies, each object's segment state (accepted, running, done,
// aborted, failed) and the status reports it produces. Must not: read a clock or talk to
// ROS: time passes only through step(), every status report is a return value the caller
// publishes. Units: metres, radians, seconds; table frame.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/clearance.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/exec/scene.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

/// A riding load reaches its carrier's front after the carrier has travelled this far (metres).
inline constexpr double kRideSwingM = 0.05;

struct TableSimulatorParams {
  /// true: robots and objects are Box2D bodies that collide; false: points that pass
  /// through each other (the paper's execution model; clearance is still measured).
  bool bodies = false;
  double object_speed_mps = 0.12;  ///< objects follow their segments at this speed
  double object_damping_hz = 8.0;  ///< table friction: a pushed object's speed decays at this rate
  int status_every_cycles = 5;     ///< a moving object reports RUNNING every N steps (10 Hz at 50 Hz)
  /// How a carry step moves its load (carry()). true: the table carries it in front of its
  /// carrier once met; false: it moves only when its carrier pushes it, as on the real table.
  bool loads_ride = true;
  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
};

/// Calls `visit(name, field)` for the fields config/execution.yaml sets under mock_robots
/// (status_every_cycles is the node's own reporting): the one list the ROS parameters and
/// `ddace eval --config` read.
template <typename Visit>
void visitParams(TableSimulatorParams& p, Visit&& visit) {
  visit("bodies", p.bodies);
  visit("object_speed_mps", p.object_speed_mps);
  visit("object_damping_hz", p.object_damping_hz);
  visit("loads_ride", p.loads_ride);
}

/// What an object reports about one of its segments (SegmentStatus on the wire).
struct ObjectStatus {
  int entity = -1;  ///< index in the task's entities
  uint32_t segment_id = 0;
  SegmentState state = SegmentState::Accepted;  ///< Accepted, Running, Done, Failed or Aborted
  double progress = 0;                          ///< arc-length fraction of the path covered, [0, 1]
  double distance_to_goal_m = 0;                ///< straight line from the object to its path's end
  std::string message;                          ///< why, for Failed and Aborted
};

class TableSimulator {
 public:
  /// `start`: every entity's pose in the task's order (scene.h's sceneStartPoses).
  /// `robot`: the parameters of every robot; robot i's noise seed is robot.seed + i.
  /// `stalled`: names of robots whose wheels are blocked. Throws ddace::Error for a start
  /// of the wrong size, invalid parameters or a stalled name that is not a robot of the task.
  TableSimulator(const task::TaskSpec& spec, const std::vector<Pose2D>& start, const DiffDriveParams& robot,
                 const TableSimulatorParams& params = {}, const std::vector<std::string>& stalled = {});
  ~TableSimulator();
  TableSimulator(TableSimulator&&) noexcept;

  /// Object `load` goes with robot `carrier` (a carry step, task::carriedLoad): from now on
  /// nothing carries it along its own segment. With params.loads_ride it rides: from where
  /// it is relative to the carrier it swings round to the carrier's front, at their contact
  /// distance, over the carrier's first kRideSwingM of travel, and then turns and moves with
  /// it, their bodies passing through each other as a load placed on its carrier does.
  /// Without, it moves only when its carrier pushes it, as on the real table
  /// (exec/push_path.h steers the carrier): with bodies by Box2D's contact of the two discs,
  /// as for any body; as points it is moved out to their contact distance along the line
  /// of their centres whenever its carrier comes nearer. A segment of the load keeps
  /// running (RUNNING reports, progress toward its goal) until endCarry(). Returns false
  /// and changes nothing when the load is farther than task::togetherDistance from its
  /// carrier, where the carrier counts as at it (a ball passed from afar moves on its own
  /// segment), or either has no body, or the load goes with another carrier. Throws
  /// ddace::Error when `carrier` is not a robot or `load` not an object.
  bool carry(int carrier, int load);
  /// The load's carrier arrived. A riding load's running segment, if any, goes on from
  /// where the load is straight to the segment's end -- the few centimetres its carrier
  /// stopped short (task::stopRadius): the load ends on its target -- and reports Done there
  /// (step()). A pushed load stays where it is and its segment is reported by the next
  /// step(): Done within the task's arrival radius plus task::kArrivalToleranceM of the
  /// segment's end (exec::CarriedObjects' rule on the real table), else Failed naming how
  /// far it is. No-op for a load nobody carries. A carrier that fails: stop the load's
  /// segment (stopSegment) instead.
  void endCarry(int load);
  /// The robot `load` goes with (carry()), or -1.
  int carrierOf(int load) const;

  /// A wheel command for robot `entity`, effective after the robot's latency. Throws
  /// ddace::Error when `entity` is not a robot.
  void commandWheels(int entity, const WheelSpeeds& wheels);

  /// A hand puts entity `entity` down at `position` (its heading kept), at rest: a riding
  /// load stops riding, a moving object stops following its segment. Throws ddace::Error
  /// for an index outside the task or a non-finite position.
  void place(int entity, const Eigen::Vector2d& position);
  /// Robot `entity`'s wheels are blocked (they do not turn, whatever is commanded) or free.
  /// Throws ddace::Error when `entity` is not a robot.
  void setStalled(int entity, bool stalled);
  /// Robot `entity`'s wheels turn at `gain` times what it commands (DiffDriveModel::setWheelGain).
  /// Throws ddace::Error when `entity` is not a robot or `gain` is not positive.
  void setWheelGain(int entity, double gain);

  /// A new segment for object `entity` along `path`, starting where the object is.
  /// Returns Accepted, or Failed for an empty path (the object then stays put), or
  /// Aborted while the e-stop is active. A copy of the running segment (same id, re-sent
  /// by the coordinator) changes nothing and returns no report; another id replaces it.
  /// Throws ddace::Error when `entity` is not an object.
  std::optional<ObjectStatus> startSegment(int entity, uint32_t segment_id, const std::vector<Eigen::Vector2d>& path);
  /// A segment refused before it reached the table (e.g. a malformed message): the running
  /// one stops where it is and `segment_id` is reported Failed with `reason`.
  ObjectStatus refuseSegment(int entity, uint32_t segment_id, const std::string& reason);
  /// MODE_STOP: the running segment, if any, stops where it is and is reported Aborted.
  std::optional<ObjectStatus> stopSegment(int entity);

  /// While active, every running segment is aborted and new ones are refused. Robots are
  /// not touched (their followers zero the wheels). Returns the Aborted reports.
  std::vector<ObjectStatus> setEstop(bool active);
  bool estopped() const { return estopped_; }

  /// Advances 1/rate_hz: robots integrate their wheels, moving objects advance along
  /// their paths. Returns Done for each object that arrived, Running every
  /// status_every_cycles steps for each still moving.
  std::vector<ObjectStatus> step();

  double time() const { return time_s_; }
  double periodS() const { return 1.0 / robot_.rate_hz; }
  size_t size() const { return entities_.size(); }
  /// The true pose of entity `i`.
  Pose2D truePose(int i) const;
  /// The pose a tracker would report: robots with the model's noise (fresh on every call),
  /// objects and goals exactly.
  Pose2D measuredPose(int i);
  /// Whether object `i` is carrying out a segment.
  bool moving(int i) const { return entity(i).moving; }
  /// Every contact between two bodies that began, in time order.
  const std::vector<BodyContact>& contacts() const { return contacts_; }
  /// The closest two bodies came (true poses, every step).
  const ClosestApproach& closestApproach() const { return meter_->closest(); }
  /// Pairs of bodies that overlapped at the start: they never collide with each other.
  const std::vector<std::pair<int, int>>& loadedPairs() const { return meter_->loadedPairs(); }
  /// The body radius of entity `i` (0 for a goal: no body).
  double radiusM(int i) const { return entity(i).radius_m; }

 private:
  struct Physics;  // the Box2D world (table_simulator.cpp)
  struct Entity {
    task::EntityKind kind;
    double radius_m = 0;                     ///< 0 = no body (goals)
    Pose2D pose;                             ///< every entity's true pose
    std::unique_ptr<DiffDriveModel> robot;   ///< robots only
    std::unique_ptr<CarriedObject> carried;  ///< the object's current (or last) segment
    uint32_t segment_id = 0;
    bool moving = false;
    // Carried (carry()): the carrier; riding, also the load's start offset in the carrier's frame, the
    // carrier's travel since, and the load's distance to its goal when it began.
    int carrier = -1;
    Eigen::Vector2d ride_offset0{0, 0};
    double ride_contact_m = 0, ride_travel_m = 0;
    int status_cycle = 0;
  };
  void checkIndex(int i) const;  ///< throws ddace::Error for an index outside the task
  const Entity& entity(int i) const;
  Entity& object(int i);
  ObjectStatus report(int i, SegmentState state, std::string message = "") const;
  void measureClearance();
  void halt(int i);  ///< object i stops following its segment (or its carrier) and comes to rest
  void rideLoads(const std::vector<Eigen::Vector2d>& before);  ///< riding loads to their carriers' fronts
  void pushLoadsApart();  ///< points: every pushed load out to contact with its carrier

  task::TaskSpec spec_;  ///< footprints and arrival radius: who carries (carry())
  std::vector<std::string> names_;
  std::vector<Entity> entities_;
  DiffDriveParams robot_;
  TableSimulatorParams params_;
  double time_s_ = 0;
  bool estopped_ = false;
  std::unique_ptr<Physics> physics_;
  std::vector<BodyContact> contacts_;
  std::vector<ObjectStatus> push_ended_;  ///< pushed loads' reports at endCarry(), out with the next step()
  std::unique_ptr<ClearanceMeter> meter_;
};

/// Whether the segment of robot token `carrier` (decided in step `carrier_step`) carries the
/// load of object token `load` (step `load_step`): the same step, and task::carriedLoad of
/// the two (same action and target). The mock robots see a step's segments one by one, in
/// any order, and pair them with this.
bool carries(const task::TaskSpec& spec, int carrier_step, const task::Token& carrier, int load_step,
             const task::Token& load);

}  // namespace ddace::exec
