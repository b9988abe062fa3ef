// Where a motion ends and when it counts as arrived: the one rule every part uses
// (docs/task-format.md, "Where a motion ends").
//
// A motion token (E, action, T) is decided with every entity's position: E starts at S,
// its target is at P. It ends at its *end point*
//
//     end = P + R(phi) * offset,   phi = the direction of P - S (the approach frame:
//                                  x from S toward P, y to its left)
//
// where `offset` (metres, approach frame) is learned from the demonstrations: for every
// demonstrated motion segment, the entity's last position relative to the target's
// position when its step was decided, in that segment's approach frame; the median (in
// polar form: the median distance along the median side) over the segments of one key
// ("R1:move:R3") when the key has at least kMinKeySegments of them, else over the segments
// of its *motion class*, else the footprints' default. Where the scene decides who does
// what, a key can hold the ends of different roles (two robots sent to one goal: the first
// stops on it, the second at the robot on it, whoever they are); so a motion class whose
// ends the step they stand in predicts better than the keys (each end against the median
// of the others of its group, by kMinRoleEndGainM per segment) is keyed by *role*: the median over the class's segments
// of that step, used before the key's where the caller knows the motion's step (the nearest demonstrated step for one
// never seen). A motion class is the mover's kind, whether it carries a load, and the target's kind: "robot->robot",
// "robot+load->goal", "object->goal". A robot carries a load when an object of its step has a token with the same
// action and target.
//
// So demonstrations that stop at contact teach end points at contact, and demonstrations
// that end at the target's centre teach end points at centres: recordings and generated
// demonstrations are read the same way. Without any demonstration the footprints decide:
// toward an obstacle (a robot, an object) the motion ends at contact, toward a goal on it;
// a carrier ends behind its load (contact with the target plus the load's diameter), the
// load on the target (or at contact with an obstacle target).
//
// When a motion has arrived, where a robot stops and when two bodies are at one place:
// task/body_geometry.h.
//
// Meant for: gp path generation (a path runs from S to the end point), the closed-loop
// simulator and the coordinator (end points of a decided step, the DONE check), the path
// follower's stop, eval's GCR; the model stores the learned offsets (primitives.yaml).
//
// Owns: the end point of a motion. Units: metres, table frame.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ddace/task/body_geometry.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_spec.h"

namespace ddace::task {

/// A key's own offset is used when it has at least this many demonstrated segments
/// (fewer: its motion class's), so one mislabelled segment cannot place a key's end.
inline constexpr int kMinKeySegments = 3;
/// A motion class's ends are keyed by role only where the steps predict held-out ends better
/// than the keys by this much per segment on average (metres). Measured, not derived: two
/// robots sent to one goal in turn gain 22 mm (the second stops at the first); the
/// generators' families 0; four robots meeting at a fifth (zoo:2) 4.6 mm, the ends round the
/// target at several sides pooled, and one of its 8 replays with bodies then deadlocked.
inline constexpr double kMinRoleEndGainM = 0.005;
/// Segments whose start is closer to the target than this have no approach direction
/// and teach nothing (metres).
inline constexpr double kMinApproachM = 0.005;

/// A learned end offset: metres in the approach frame, and the segments it comes from.
struct EndOffset {
  Eigen::Vector2d offset{0, 0};
  int segments = 0;
};

/// The learned end points of a task's motions.
struct EndPointModel {
  std::map<std::string, EndOffset> by_key;    ///< "R1:move:R3"
  std::map<std::string, EndOffset> by_class;  ///< "robot->robot", "robot+load->goal", ...
  /// Classes keyed by role (header comment): class -> step (0-based) -> offset, each step's
  /// from at least kMinKeySegments segments.
  std::map<std::string, std::map<int, EndOffset>> by_role;
  /// The same ends keyed by name and class only (the paper's keys, to compare against).
  EndPointModel byName() const {
    EndPointModel m = *this;
    m.by_role.clear();
    return m;
  }
  /// True for a model trained before end points were learned: every motion ends at its
  /// target's centre, as those models were trained (primitives.yaml /2).
  bool centres = false;
};

/// The index in `step` of the object token that the robot token `step[i]` carries (same
/// action and target), or -1 (not a robot, not a motion, no load).
int carriedLoad(const TaskSpec& spec, const std::vector<Token>& step, size_t i);
/// The motion class of `step[i]` (a motion token): "<mover kind>[+load]-><target kind>".
std::string motionClass(const TaskSpec& spec, const std::vector<Token>& step, size_t i);

/// Learns the offsets from every motion segment of `demos` (analyzed demonstrations of
/// `spec`).
EndPointModel learnEndPoints(const TaskSpec& spec, const std::vector<Demonstration>& demos);

/// The offset the rule uses for `step[i]` (approach frame, metres): its role's when
/// `step_index` (the step it stands in, 0-based; < 0: unknown) is given and its class is keyed
/// by role, the key's, its class's, or the footprints' default (see the header comment).
Eigen::Vector2d endOffset(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i,
                          int step_index = -1);

/// Where the demonstrations stop toward a body at another gap than the footprints' contact
/// (robots left 4 mm or 1 cm apart; or overlapping: footprints stated too big): a wider gap
/// is kept as demonstrated, an overlap ends at the footprints' contact (the filter and the
/// collision judge hold bodies to the footprints); training names both (stopGaps).
struct StopGap {
  std::string motion;  ///< the key, "R2:move:R1"
  std::string mover, target;
  double gap_m = 0;       ///< the end point's distance from the target less their contact distance (< 0: overlap)
  int segments = 0;       ///< the demonstrated segments it comes from
  bool by_class = false;  ///< from its motion class's segments (the key has fewer than kMinKeySegments)
  /// "R2 stops 4 mm from R1 in the demonstrations (12 stops); footprints say 0 mm: using
  /// the demonstrated gap".
  std::string str() const;
};
/// Every motion of `demos` (once per key) toward an obstacle, without a load, whose end
/// point under `model` (learned from `demos`) lies a whole millimetre or more off contact
/// with its target: the demonstrated gap differs from the footprints'.
std::vector<StopGap> stopGaps(const TaskSpec& spec, const EndPointModel& model,
                              const std::vector<Demonstration>& demos);

/// The end point of the motion token `step[i]` decided with entity positions `decided`
/// (table frame, metres), standing in step `step_index` (endOffset()). An in-place token ends
/// where it is. Throws ddace::Error for a
/// token naming an entity outside `decided`.
Eigen::Vector2d endPoint(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i,
                         const std::vector<Eigen::Vector2d>& decided, int step_index = -1);

/// The end point the rule gives a demonstrated segment (its step's tokens, decided with the
/// step's snapshot); the segment's goal (Demonstration::segmentGoal) when its step is unknown.
Eigen::Vector2d segmentEndPoint(const TaskSpec& spec, const EndPointModel& model, const Demonstration& demo,
                                const Segment& segment);

/// The end point from a start, the target's position and an offset (the rule's geometry):
/// S when S is within kMinApproachM of P (already there).
Eigen::Vector2d endPointFrom(const Eigen::Vector2d& start, const Eigen::Vector2d& target,
                             const Eigen::Vector2d& offset);

/// Where bodies fit (stepEndPositions): a turned end point is searched in steps of
/// kEndTurnStepRad, at most kMaxEndTurnRad either way about the target, and stays
/// kEndTurnGapM (metres) from every body but its target (so 1-1.4 cm off them, nearer than
/// the safety filter would hold a robot arriving beside them: execution lets it end against
/// them, exec::SafetyParams::endsAgainstReachM); onto a taken goal the motion backs off
/// kBackOffStepM (metres) at a time.
inline constexpr double kEndTurnStepRad = M_PI / 36;  // 5 degrees
inline constexpr double kMaxEndTurnRad = M_PI / 2;
inline constexpr double kEndTurnGapM = 0.01;
inline constexpr double kBackOffStepM = 0.001;
/// The index in `step` of the load the robot token `step[i]` carries *and that rides with
/// it* (carriedLoad(), starting within togetherDistance() of its carrier in `at`; a load
/// of two carriers rides with the first), or -1. A ball passed from afar to where a robot
/// also goes moves on its own.
int ridingLoad(const TaskSpec& spec, const std::vector<Token>& step, size_t i, const std::vector<Eigen::Vector2d>& at);

/// Where every entity stands after `step` decided with entity positions `decided` when
/// bodies must fit (table frame, metres). Each motion ends at its endPoint() under `model`
/// (in step `step_index`);
/// a riding load (ridingLoad()) ends in front of its carrier at their contact distance
/// along the carrier's approach (on the target, the carrier behind it). Its own target a
/// motion comes no nearer than their contact (demonstrations stopping inside the
/// footprints end at contact: the footprints are what bodies are held to). An end point inside a standing body, or
/// inside an end placed before it in the step (token order), is turned about the target to the nearest place at the
/// same distance kEndTurnGapM clear of every other body (the motion still touches its target, and only it); where no
/// turn frees it (a goal another body already stands on) it stops short on its way where its body first fits: two
/// robots sent onto one goal end touching, one on it. With `table` (its corners), no end is moved further over its edge
/// than its entity starts. Used wherever a step is executed with bodies: the generated demonstrations (with nothing
/// learned), `ddace eval` with bodies and the coordinator. Throws ddace::Error for a token naming an entity outside
/// `decided`.
std::vector<Eigen::Vector2d> stepEndPositions(const TaskSpec& spec, const EndPointModel& model,
                                              const std::vector<Token>& step,
                                              const std::vector<Eigen::Vector2d>& decided,
                                              const std::optional<Eigen::AlignedBox2d>& table = std::nullopt,
                                              int step_index = -1);

}  // namespace ddace::task
