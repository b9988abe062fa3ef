// Motion primitives: how an entity moves for one (entity, action, target) key, learned
// from the demonstrations and retargeted to new starts and goals (DDACE, Sec. IV-C).
//
// Fitting. For every motion key (a token with a target), every segment of that key in
// every demonstration is taken (Demonstration::segmentPath), resampled to `points`
// points by progress (arc-length fraction, gp/canonical.h) and expressed in its own
// canonical frame (start at the origin, start->end along +x, start-end distance 1).
// Two GPs (gp/gaussian_process.h) are trained on all segments of the key: the x-GP
// maps normalised progress s in [0, 1] to canonical x, the y-GP to canonical y. All
// segments share the same progress values, so each GP is fitted on `points` distinct
// inputs whatever the number of demonstrations. Segments shorter than
// `min_segment_length_m` have no canonical frame and are skipped (and counted).
//
// Generation. The GPs' mean at `points` progress values is retargeted to the new start
// S and goal G: p = S + |G - S| R(phi) c, phi the direction of G - S (the inverse
// rotation, scaling and translation of the canonical frame). With `pin_endpoints` the
// canonical mean is first corrected by a linear blend, c(s) += (1 - s)(0 - c(0)) +
// s((1, 0) - c(1)), so the path starts exactly at S and ends exactly at G (the correction
// is what the GP mean misses at the ends, typically < 1e-3 canonical units).
// stddev[i] = |G - S| * sqrt((sx^2 + sy^2) / 2): the RMS of the per-axis predictive
// standard deviations (white noise included, i.e. the spread of demonstrations),
// in metres; it does not depend on the direction of G - S.
//
// Roles. Where the scene decides who does what, one name's key can hold the motions of
// different roles (in a line-up R2:move:R1 is sometimes the second robot joining the head,
// sometimes the third joining the second). A motion class (the mover's kind, the action,
// the target's kind: "robot:hamster/move/goal") is keyed by role when that predicts held-out
// demonstrations better than the names do: each of the class's segments is predicted by the
// mean of the others of its group (a group of one: of the whole class), once grouped by key
// and once by the step the motion stands in, and the smaller summed error wins (the names
// on a tie, and always where both group alike, as a fixed order's steps and names do). A
// class keyed by role gets one primitive per demonstrated step, key
// "robot:hamster/move/goal@2" (0-based step), fitted on every segment of the class in that
// step whoever moved; generate() with the motion's step takes the class's primitive of
// that step (or of the nearest demonstrated one), for any entity of those kinds, one
// never seen included. The per-name primitives are fitted as well: a caller that gives no
// step (step < 0) gets them, as before.
//
// Fallback for a key that was never demonstrated, in this order:
//   1. the same entity and action toward another target of the same kind,
//   2. the same action by an entity of the same kind toward a target of the same kind (a
//      robot the library never saw, boundTo),
//   3. the same entity and action toward any target, 4. the same action by any entity,
//   5. a straight line from S to G with stddev 0 (source_key "straight line");
// within 1-4 the primitive with the most segments wins, ties by key order.
// The result says so (fell_back, source_key).
//
// End points. The library also holds where the demonstrated motions ended relative to
// their targets (task/end_point.h, learned by fit(), by role where the step tells them
// better than the names): the paths a caller asks for run from the start to the end point
// that rule gives (generate() takes it as `goal`).
//
// File: <modeldir>/primitives.yaml (format ddace-primitives/5), documented in docs/gp.md.
// A /4 file (before end points by role) reads with its end points by name and class; a /3
// file (before roles) as a library keyed by name; a /2 file (before end points were
// learned) also reads: its motions end at their targets' centres, as it was trained.
//
// A library is immutable after fit()/load(): generate() may be called from several
// threads at once.
//
// Owns: primitives, their library and file. Must not: decide which tokens run (tgn)
// or drive anything (exec).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/gp/gaussian_process.h"
#include "ddace/task/end_point.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/fingerprint.h"
#include "ddace/task/task_dir.h"

namespace ddace::gp {

/// /2: the library names the task fingerprint it was fitted on (task/fingerprint.h).
/// /3: and the learned end points (task/end_point.h). /4: and the role primitives. /5: and
/// the end points of the motion classes keyed by role.
inline constexpr const char* kPrimitivesFormat = "ddace-primitives/5";
/// Read as a library whose end points are by name and class only, as it was trained.
inline constexpr const char* kPrimitivesFormatWithoutRoleEnds = "ddace-primitives/4";
/// Read as a library keyed by name only.
inline constexpr const char* kPrimitivesFormatWithoutRoles = "ddace-primitives/3";
/// Read as: every motion ends at its target's centre.
inline constexpr const char* kPrimitivesFormatWithoutEndPoints = "ddace-primitives/2";
/// Largest end offset a file may hold, metres (a table is about 1 m).
inline constexpr double kMaxEndOffsetM = 10.0;
inline constexpr const char* kPrimitivesFile = "primitives.yaml";
inline constexpr const char* kStraightLine = "straight line";

/// C*RBF + White with bounds for canonical coordinates: C in [1e-4, 1e2],
/// l in [1e-2, 10] (progress units), sigma_n^2 in [1e-6, 1]; initial (0.1, 0.2, 1e-4);
/// 2 restarts, seed 0, alpha 1e-10.
GpOptions defaultPrimitiveGpOptions();

/// Bounds of what primitives.yaml may ask for, checked before anything is allocated: a GP
/// holds points x points matrices, and segments only weight the fit.
inline constexpr int kMaxPrimitivePoints = 2000;
inline constexpr int kMaxPrimitiveSegments = 1000000;

struct PrimitiveOptions {
  int points = 100;                            ///< progress samples per segment (distinct GP inputs)
  double min_segment_length_m = 0.005;         ///< shorter segments are skipped, metres
  bool pin_endpoints = true;                   ///< generated paths start at S and end at G exactly
  GpOptions gp = defaultPrimitiveGpOptions();  ///< for both the x- and the y-GP
};

struct GeneratedPath {
  std::vector<Eigen::Vector2d> points;  ///< table frame, metres, start..goal
  std::vector<double> stddev;           ///< per point, metres (see the header comment)
  bool fell_back = false;               ///< true when the key was never demonstrated
  std::string source_key;               ///< primitive actually used ("straight line" when none)
};

/// The training data of one motion key: its segments, each resampled to `points` points by
/// progress and expressed in its own canonical frame (dimensionless).
struct KeySegments {
  task::Token token;
  std::vector<std::vector<Eigen::Vector2d>> canonical;  ///< [segment][point]
  std::vector<int> steps;                               ///< [segment] the step it stands in
  int skipped = 0;                                      ///< segments shorter than min_segment_length_m
};

/// What PrimitiveLibrary::fit() trains on, by key ("R1:move:R3"). Throws ddace::Error for
/// invalid options.
std::map<std::string, KeySegments> canonicalSegments(const task::TaskDir& train, const PrimitiveOptions& options = {});

/// A motion class: "robot:hamster/move/goal" (the mover's kind, the action, the target's).
std::string motionClass(const std::string& entity_kind, const std::string& action, const std::string& target_kind);
/// A role primitive's key: "robot:hamster/move/goal@2".
std::string roleKey(const std::string& motion_class, int step);

/// One learned primitive: of a name's key, or of a role (step >= 0).
struct Primitive {
  std::string key;                     ///< "R1:move:R3", or a role's "robot:hamster/move/robot:hamster@1"
  std::string entity, action, target;  ///< names; of a role: the mover's and the target's kinds
  int step = -1;                       ///< a role's step (0-based); -1: a name's primitive
  int segments = 0;                    ///< segments trained on
  int skipped_segments = 0;            ///< too short to have a canonical frame
  GaussianProcess x, y;                ///< canonical x and y as functions of progress
};

class PrimitiveLibrary {
 public:
  PrimitiveLibrary() = default;

  /// Fits one primitive per motion key of `train`. Throws ddace::Error for invalid options.
  static PrimitiveLibrary fit(const task::TaskDir& train, const PrimitiveOptions& options = {});

  /// Writes the library as YAML (format kPrimitivesFormat). Throws ddace::Error naming
  /// the file when it cannot be written.
  void save(const std::string& path) const;
  /// The text save() writes.
  std::string text() const;
  /// Reads a library written by save(). Throws ddace::Error naming the file and listing
  /// every problem with its line and column (common/yaml_checker.h): unreadable, not YAML,
  /// wrong format, an unknown key, a missing or invalid field, YAML aliases, or numbers
  /// that do not reproduce the stored likelihood (checked once every field is sound: the
  /// GPs are rebuilt, in cubic time, only then).
  static PrimitiveLibrary load(const std::string& path);
  /// The same from the file's bytes (`path` names it in messages).
  static PrimitiveLibrary parse(const std::string& text, const std::string& path);

  /// A path for `token` from `start` to `goal` (table frame, metres) with `points` >= 2
  /// points, the motion standing in step `step` (0-based; < 0: unknown, the name's
  /// primitive). Throws ddace::Error for an in-place token, an entity index outside the
  /// library's task, or points < 2. A start within 1 micrometre of the goal gives
  /// `points` copies of the start (nothing to move).
  GeneratedPath generate(const task::Token& token, const Eigen::Vector2d& start, const Eigen::Vector2d& goal,
                         int points = 100, int step = -1) const;
  /// The same for a key "E:action:T" naming the library's entities (ddace path), or a role
  /// key as primitives() lists it ("KIND/ACTION/KIND@STEP": that primitive, `step` unused).
  GeneratedPath generate(const std::string& key, const Eigen::Vector2d& start, const Eigen::Vector2d& goal,
                         int points = 100, int step = -1) const;
  /// The motion classes keyed by role (header comment, "Roles").
  std::vector<std::string> roleClasses() const;

  /// The library on the entities of `other`, a task of the same kinds of entity in other
  /// numbers or names (tgn::SequenceModel::boundTo): tokens and keys name other's entities;
  /// a motion of an entity the library never saw falls back as any undemonstrated key.
  /// Throws ddace::Error naming a kind of entity one of them has and the other lacks.
  PrimitiveLibrary boundTo(const task::TaskSpec& other) const;

  /// Canonical mean and per-axis standard deviation of a primitive at `points` progress
  /// values (before retargeting; endpoint pinning applied when enabled).
  void canonical(const Primitive& primitive, int points, std::vector<Eigen::Vector2d>& mean,
                 std::vector<Eigen::Vector2d>& stddev) const;

  const std::map<std::string, Primitive>& primitives() const { return primitives_; }
  const std::vector<std::string>& entityNames() const { return entities_; }
  const std::string& taskName() const { return task_; }
  /// The fingerprint of the training directory the library was fitted on.
  const task::TaskFingerprint& taskFingerprint() const { return fingerprint_; }
  const PrimitiveOptions& options() const { return options_; }
  /// Where the demonstrated motions ended (task/end_point.h).
  const task::EndPointModel& endPoints() const { return end_points_; }

 private:
  friend class LibraryReader;  // parse()'s parts (primitives.cpp)
  /// The primitive for (entity, action, target) names in `step` (roles, then names after
  /// the fallback rule), or null.
  const Primitive* lookup(const std::string& entity, const std::string& action, const std::string& target, int step,
                          bool& fell_back) const;
  /// Indexes the role primitives by class and step (after fit() and parse()).
  void indexRoles();
  GeneratedPath generateFrom(const Primitive* primitive, bool fell_back, const Eigen::Vector2d& start,
                             const Eigen::Vector2d& goal, int points) const;
  void cacheGrid();
  /// Entity name -> "KIND" or "KIND:TYPE", from a fingerprint's entities.
  static std::map<std::string, std::string> kindsOf(const task::TaskFingerprint& fingerprint);

  std::string task_;
  std::vector<std::string> entities_;
  task::TaskFingerprint fingerprint_;
  /// The kinds of the entities tokens name (the task bound to, boundTo) and of the
  /// training task's (the primitives').
  std::map<std::string, std::string> kinds_, trained_kinds_;
  PrimitiveOptions options_;
  task::EndPointModel end_points_;
  std::map<std::string, Primitive> primitives_;
  /// Role primitives' keys by class and step.
  std::map<std::string, std::map<int, std::string>> roles_;
  /// Canonical mean/stddev on the training grid, per key: generation at the default
  /// number of points needs no GP evaluation.
  std::map<std::string, std::pair<std::vector<Eigen::Vector2d>, std::vector<Eigen::Vector2d>>> grid_;
};

}  // namespace ddace::gp
