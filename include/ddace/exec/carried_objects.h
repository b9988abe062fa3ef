// The segments of objects on a table where nothing but their carriers moves them (the real
// table: a box has no wheels and no executor). An object's segment is judged from tracking:
//
//   done    when its carrier's segment (the robot segment of the same step that carries it,
//           exec::carries) is done and the tracker sees the object within the arrival
//           radius plus the tracking tolerance of the segment's end point;
//   failed  when the carrier is done and the object is not seen there within settle_s
//           (the message names the object, where it is and how far from its end point),
//           when the carrier's segment fails or is aborted, or when no robot segment of its
//           step carries it within pairing_s of its own (nothing would move it);
//   aborted when the coordinator cancels it (MODE_STOP, e-stop).
//
// A task whose demonstrations move an object with no robot carrying it in the same step
// cannot run there: uncarriedObjectMotion() names the first such token, for a refusal at
// start.
//
// Owns: the pairing of object segments with their carriers, and the judgement of object
// segments from tracked positions. Must not: talk ROS, read clocks (time comes in as
// `now_s`), move anything.
// Units: metres, seconds; table frame.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/table_simulator.h"
#include "ddace/task/end_point.h"
#include "ddace/task/task_dir.h"

namespace ddace::exec {

struct CarriedObjectParams {
  /// An object is at its end point within arrival_radius_m + arrival_tolerance_m (the
  /// coordinator's DONE check, exec::CoordinatorConfig).
  double arrival_radius_m = task::kDefaultArrivalRadius;
  double arrival_tolerance_m = task::kArrivalToleranceM;
  /// After its carrier is done, the object has this long to be seen at its end point (the
  /// tracker's latency and a box still sliding), seconds.
  double settle_s = 2.0;
  /// An object segment with no carrier segment of its step after this long fails, seconds
  /// (the coordinator sends a step's segments together; a dispatch that released a carrier
  /// later than its load would need the time it waits here).
  double pairing_s = 1.0;
  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
};

/// Why `dir` cannot run on the real table, or nothing: "task 'T': B1:move:G1 (demonstration
/// 3, step 2) moves an object with no robot carrying it in its step; ...", the first object
/// motion token of its demonstrations that no robot token of its step carries
/// (task::carriedLoad).
std::optional<std::string> uncarriedObjectMotion(const task::TaskDir& dir);

class CarriedObjects {
 public:
  /// Throws ddace::Error when `params` are invalid.
  CarriedObjects(task::TaskSpec spec, CarriedObjectParams params);

  /// A robot's segment as sent to its follower (step, token): a carrier when an object
  /// segment of the same step is carried by it. Replaces the robot's earlier segment.
  void onRobotSegment(int robot, uint32_t segment_id, int step, const task::Token& token);
  /// The robot's follower reported on its segment (Done, Failed, Aborted matter).
  std::vector<ObjectStatus> onRobotStatus(int robot, uint32_t segment_id, SegmentState state, double now_s);
  /// An object's segment: Accepted (the judgement follows), or Failed at once for a token
  /// that is not the object's own motion.
  std::vector<ObjectStatus> onObjectSegment(int object, uint32_t segment_id, int step, const task::Token& token,
                                            const Eigen::Vector2d& goal, double now_s);
  /// The coordinator cancelled the object's segment: Aborted (nothing when none runs).
  std::vector<ObjectStatus> stopObject(int object);
  /// The tracker's latest positions (index = task order; `tracked` false: not seen now).
  void onPositions(const std::vector<Eigen::Vector2d>& positions, const std::vector<bool>& tracked);
  /// Done and time-outs; call at the tracker's rate or on a timer.
  std::vector<ObjectStatus> update(double now_s);

  /// The robot carrying the object's running segment, or -1.
  int carrierOf(int object) const;

 private:
  struct Running {
    uint32_t segment_id = 0;
    int step = -1;
    task::Token token;
    Eigen::Vector2d goal{0, 0};
    double since_s = 0;
    double start_distance_m = 0;  ///< from where it was when its segment came, for progress
    int carrier = -1;
    double carrier_done_s = -1;  ///< when its carrier reported done (-1: not yet)
  };
  struct RobotSegment {
    uint32_t segment_id = 0;
    int step = -1;
    task::Token token;
  };

  void pair(Running& r);
  ObjectStatus status(int object, const Running& r, SegmentState state, const std::string& message) const;
  double distance(int object, const Running& r) const;
  const std::string& name(int entity) const { return spec_.entities[static_cast<size_t>(entity)].name; }

  task::TaskSpec spec_;
  CarriedObjectParams params_;
  std::map<int, Running> objects_;      ///< each object's running segment
  std::map<int, RobotSegment> robots_;  ///< each robot's latest segment
  std::vector<Eigen::Vector2d> positions_;
  std::vector<bool> tracked_;
};

}  // namespace ddace::exec
