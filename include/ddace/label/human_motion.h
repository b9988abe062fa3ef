// Demonstrations moved as a person moves robots by hand and seen through a tracker, made
// from a generated demonstration (tasks/generators.h), to measure label inference on every
// family (docs/labels.md): the same steps, tokens and paths, re-timed and disturbed.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "ddace/common/random.h"
#include "ddace/label/label.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/task_dir.h"

namespace ddace::label {

struct HumanMotionOptions {
  double rate_hz = 30;                             ///< the recorder's rate
  double onset_spread_s = 1.0;                     ///< the robots of a step start up to this far apart
  double speed_min = 0.6, speed_max = 1.6;         ///< each motion's speed, times the generated one
  double pause_probability = 0.3;                  ///< a motion stops once on the way...
  double pause_min_s = 0.4, pause_max_s = 1.2;     ///< ...for this long
  double nudge_probability = 0.3;                  ///< after a step, a resting robot is bumped and put back...
  double nudge_min_m = 0.01, nudge_max_m = 0.025;  ///< ...this far
  double gap_min_s = 0.5, gap_max_s = 1.5;         ///< a person's time between two steps
  double in_place_s = 1.0;                         ///< an in-place-only step lasts this long
  double noise_m = 0.0015;                         ///< tracker noise, std-dev per coordinate
  double hold_probability = 0.02;                  ///< a dropped frame starts a hold (the tracker repeats the pose)...
  int hold_max_rows = 6;                           ///< ...of up to this many rows
  /// How a motion gathers and sheds speed along its path: Eased as generated (smoothstep),
  /// Constant, Brisk (quick start, long braking), Late (slow start, hard stop). Mixed: one
  /// of the four drawn per motion.
  enum class Profile { Eased, Constant, Brisk, Late, Mixed } profile = Profile::Eased;
  /// A robot driven to touch a robot or an object stops this much short of contact.
  double contact_gap_min_m = 0, contact_gap_max_m = 0;
  /// A robot sent to a goal another body stands on ends touching the body it reaches there,
  /// turned about that body by up to this (either side) from where the generator put it.
  double beside_max_rad = 0;
  /// true: each motion's label begins at its own onset (a person keying each robot as it
  /// starts), not at its step's first onset; a robot started after another of its step
  /// stopped then reads as a step of its own (docs/task-format.md, "Step grouping").
  bool label_at_own_onset = false;
};

/// A named way of demonstrating (`ddace bench label_styles`): one aspect of a person's
/// motion varied from `calm` (steps a second apart, robots of a step starting together,
/// the generated motion, no camera), or all of them at once.
struct DemonstrationStyle {
  std::string name, description;
  HumanMotionOptions options;
};
/// calm, pause, onset, speed, contact, occupied, bump, camera, all.
std::vector<DemonstrationStyle> demonstrationStyles();
/// The style named `name`; throws ddace::Error naming it when there is none.
DemonstrationStyle demonstrationStyle(const std::string& name);
/// The seed of style `name`'s demonstrations in a measurement seeded `seed`: each style
/// its own, by its place in demonstrationStyles() (the same when one style is measured).
uint64_t styleSeed(uint64_t seed, const std::string& name);

/// fetch_then_occupied_goal, a family the generators lack, made with their motion
/// (tasks::simulateSteps) from fetch's scenes: the robot nearest the box fetches it and
/// pushes it onto G1, then the other robot drives to G1 as well and ends at the bodies
/// that occupy it (a drive to an occupied goal).
constexpr const char* kOccupiedGoalFamily = "fetch_then_occupied_goal";
task::TaskDir occupiedGoalFamily(int demos, uint64_t seed);

/// `clean` (analyzed, labelled, as generated) moved by a person: per step, each motion
/// starts up to onset_spread_s after the first (a load with its carrier), at its own speed,
/// perhaps pausing; robots bumped between steps; noise and held poses. The labels are the
/// true ones: every token of a step from the step's first onset (label_at_own_onset: a
/// motion's from its own) to the end of its own motion (in-place tokens: to the step's
/// end). The result is analyzed and has clean's steps (label_at_own_onset: perhaps split,
/// a step read as two where a robot started after another of it stopped).
task::Demonstration humanMotion(const task::Demonstration& clean, const task::TaskSpec& spec,
                                const HumanMotionOptions& options, SplitMix64& rng);

/// How inferred labels compare with the true ones on one or more demonstrations.
struct LabelScore {
  int true_tokens = 0, inferred_tokens = 0, matched = 0;  ///< same entity, action, target, step
  int demos = 0, demos_exact = 0;                         ///< demonstrations with exactly the true steps
  int notes = 0;                                          ///< uncertain items reported
  /// Inferred tokens: not matched (wrong), listed to check (unsure), and both.
  int wrong = 0, listed = 0, wrong_listed = 0;
  int demos_wrong = 0, demos_wrong_listed = 0;        ///< demonstrations with a wrong token; of them, with one listed
  double wrongListed() const;                         ///< wrong_listed / wrong; 1 when none is wrong
  double listedWrong() const;                         ///< wrong_listed / listed; 0 when none is listed
  std::vector<double> onset_error_s, offset_error_s;  ///< per matched token, seconds
  /// Listed tokens by the kind of note that listed them (doubtKind): {listed, of them wrong}.
  std::map<std::string, std::array<int, 2>> listed_by_doubt;
  double accuracy() const;  ///< matched / max(true, inferred); 1 when both are empty
  void add(const LabelScore& o);
};

/// The kind of a note (label::Note), for a breakdown of the listed tokens: "stopped
/// halfway", "ended between", ... (the message's fixed words).
std::string doubtKind(const std::string& message);

/// Compares `inferred` (labels applied by applyLabels from `inference`) with `truth`
/// (same rows); a token is listed when the inference is unsure of it.
LabelScore scoreLabels(const task::Demonstration& truth, const task::Demonstration& inferred,
                       const Inference& inference);

/// A training set moved by a person (`generated`'s demonstrations through humanMotion) with
/// its true labels, and the same set labelled from its motion: the first demonstration
/// labelled by hand (kept as it is, and the example of the others), the others inferred.
/// `score` compares the inferred ones with the truth.
struct InferredDataset {
  task::TaskDir truth, inferred;
  LabelScore score;
  std::vector<std::vector<Note>> notes;  ///< [demo] the inference's (none for the example)
};
/// `truth`'s steps are grouped across its demonstrations (task::groupStepsAcrossDemonstrations)
/// as a task directory read from disk.
InferredDataset inferredDataset(const task::TaskDir& generated, const HumanMotionOptions& options, uint64_t seed);

/// The median of `v` (0 for none).
double median(std::vector<double> v);

}  // namespace ddace::label
