// Labels inferred from tracked motion (docs/labels.md): a person only demonstrates, the
// tokens of ddace-task/1 are read off the positions.
//
// Streaming: feed rows in order with MotionSegmenter::row(); memory holds a few seconds of
// rows and the motions found so far (a few numbers each), never the recording. Positions
// are metres in the table frame, times seconds.
//
// What is read from motion (docs/task-format.md, "Semantics"):
//   - a token begins when an entity starts to move and ends when it stops; a pause in the
//     middle (stopped away from every entity, then on again) is one token, and a motion
//     that comes back to where it began (a nudge) is none;
//   - a step boundary is the moment every moving entity has stopped: motions that overlap
//     in time (or are joined by a pause) form one step, all of its tokens begin at the
//     step's first onset (the moment the step was decided);
//   - a token's target is the entity it ends at (endPoint(): the one end-point reading);
//   - a load is an object that moves with a robot (at most touching it all the way): its
//     token gets its carrier's target and word.
// In-place actions leave no trace in motion; they come from a labelled example (label.h).
#pragma once

#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/task/task_spec.h"

namespace ddace::label {

/// Thresholds of the segmentation. Every one follows from the task's arrival radius r (the
/// precision the task asks of an end point) and the tracker, never from a task family.
struct SegmentationOptions {
  /// An entity has started to move when it is this far from where it rested: r / 2.
  double start_m = 0.015;
  /// It rests when its positions over `still_s` stay within this of their mean: r / 6, above
  /// the tracker's noise (3 sigma). So a motion slower than 2 still_m / still_s (2.5 cm/s)
  /// reads as resting, and a pause shorter than still_s as none.
  double still_m = 0.005;
  double still_s = 0.4;
  /// Onset and offset are dated back to the last (first) row whose position, averaged over
  /// 5 rows, is within this of the rest position: 3 sigma of the tracker's noise
  /// (1.5 mm per coordinate) after averaging.
  double edge_m = 0.0025;
  /// A motion that arrived somewhere and goes on within pause_s in the heading it came in
  /// (within this angle, radians) is one motion paused on its way over an entity.
  double heading_rad = 0.5;
  /// A motion whose end is less than this from its start is a nudge, not a token: r.
  double nudge_m = 0.03;
  /// A motion that stopped away from every entity and goes on within this is one token
  /// (a person's pause); longer, it is reported as stopped halfway.
  double pause_s = 3.0;
  /// Rows kept for dating onsets back, seconds.
  double history_s = 4.0;
  /// The task's arrival radius, metres.
  double arrival_m = task::kDefaultArrivalRadius;

  /// The thresholds above for a task's arrival radius.
  static SegmentationOptions forTask(const task::TaskSpec& spec);
};

/// One motion of one entity: [on_row, off_row] (rows 0-based), start and end positions,
/// and where every entity was at its onset.
struct Motion {
  int entity = -1;
  int on_row = 0, off_row = 0;
  double on_t = 0, off_t = 0;
  Eigen::Vector2d start = Eigen::Vector2d::Zero(), end = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> at_onset;   ///< [entity] positions at on_row
  std::vector<Eigen::Vector2d> at_offset;  ///< [entity] positions at off_row
  /// [entity] the largest distance to that entity over the motion (load detection), and
  /// the smallest (what it touched on its way).
  std::vector<double> max_distance, min_distance;
  /// [entity] the mover's least speed while it was closest to that entity (within still_m
  /// of its least distance), m/s: a stop there.
  std::vector<double> closest_speed;
  /// [entity] (distance, speed) of the rows within still_m of the least distance so far
  /// that were slower than every row nearer: closest_speed is the last one's speed, and a
  /// row left outside as the least distance falls is dropped (a slow start farther away
  /// is no stop at the body).
  std::vector<std::vector<std::pair<double, double>>> slow_near;
  std::vector<Eigen::Vector2d> closest_at;  ///< [entity] where the mover was when closest to it
  /// [entity] the row and time it was closest to that entity, and where every entity stood
  /// then (a cut there: a stop at a body without a pause).
  std::vector<int> closest_row;
  std::vector<double> closest_t;
  std::vector<std::vector<Eigen::Vector2d>> closest_scene;
  /// Takes `o`'s closest approaches (speed, place, time) to the entities it came closer to.
  void absorbClosest(const Motion& o);
  /// Goes on as `o`, its later motion: `o`'s offset, end and last leg, the farthest and
  /// closest approaches of both (the whole offset is the caller's).
  void continueWith(const Motion& o);
  bool resumed = false;  ///< joined from two motions across a pause
  /// Where its last piece began (joined across a pause: where it went on from): the line
  /// it came in on, as the end-point rule reads an approach.
  Eigen::Vector2d leg_start = Eigen::Vector2d::Zero();
  /// It began as a creep (slower than a rest reads, found once it was start_m away).
  bool crept = false;
  /// Where the entity rested before this motion, nudges aside (MotionSegmenter's home).
  Eigen::Vector2d rested_at = Eigen::Vector2d::Zero();
  /// Cut where what moved with it changed (label.h): the whole motion's offset (row, time);
  /// the motion's own for one not cut.
  int whole_off_row = -1;
  double whole_off_t = 0;
  /// Unit headings: of the first start_m of the motion and of its last start_m.
  Eigen::Vector2d start_dir = Eigen::Vector2d::UnitX(), end_dir = Eigen::Vector2d::UnitX();
};

/// Where a motion ends (the end-point reading; the one place that decides it).
struct EndPoint {
  int target = -1;  ///< entity it ended at, -1 for none
  /// Other entities it could as well have ended at (a tie: residuals within half the
  /// arrival radius of the best), empty when the end point is clear.
  std::vector<int> tied;
  double residual = 0;   ///< metres off the best reading
  int nearest = -1;      ///< the nearest entity (for a report when target is -1)
  double nearest_m = 0;  ///< its distance, metres
};

/// The entity a motion of `mover` from `start` to `end` ended at, among `candidates` (their
/// positions in `where`, [entity], when the motion began). Two readings are accepted, each
/// within the arrival radius: the centre of the target (a generated demonstration ends on
/// its target), or the end point the task's one end-point rule gives this motion without
/// anything learned (task/end_point.h: at contact with an obstacle's body, on a flat goal,
/// a carrier behind its `load`, -1 for none). Two more count half the arrival radius worse
/// (where a body already stood, the generators end a motion so, generators.h): beside an
/// obstacle target on another side (up to half the radius short of touching it: as far as
/// a reading half the radius worse stays within it; a person stops short of a body, as on
/// the line), and stopped on the way short of a goal by up to the mover's diameter. A goal
/// bodies stand on when the motion ended (`at_end`, [entity]; `where` when null: one may
/// have arrived in the same step) is also read where the mover ends touching one of them.
/// `touching`: whether a motion stopped *at* a body (a pause there, not the motion's
/// target): another side reads only touching it, within a quarter of the radius (five times
/// the tracker's noise), so a body it merely stopped near is not read.
EndPoint endPoint(const task::TaskSpec& spec, int mover, const Eigen::Vector2d& start, const Eigen::Vector2d& end,
                  const std::vector<Eigen::Vector2d>& where, const std::vector<bool>& candidates, int load = -1,
                  const std::vector<Eigen::Vector2d>* at_end = nullptr, bool touching = false);

/// Finds motions row by row. Call row() for every row in order, then finish().
class MotionSegmenter {
 public:
  MotionSegmenter(size_t entities, const SegmentationOptions& options);

  void row(double t, const std::vector<Eigen::Vector2d>& positions);
  /// Closes motions still running at the last row (their offset: the last row).
  void finish();

  /// Motions found so far, nudges included (a motion paused on its way may go on: the
  /// labeller joins the pieces before it leaves out what ends where it began), in order of
  /// their offset. take() hands them over, so memory stays bounded for a long recording.
  std::vector<Motion> take();
  /// True when no entity is moving: a step may be over.
  bool allResting() const;
  /// A row and its time, seconds.
  struct Horizon {
    int row = 0;
    double t = 0;
  };
  /// No motion handed over later begins before this row: the onset of a running motion,
  /// else the oldest row kept (an onset is dated back within the rows kept). After
  /// finish(): INT_MAX and infinity.
  Horizon horizon() const;
  /// The row index of the next row().
  int rows() const { return row_; }
  /// Time of the last row.
  double lastT() const { return last_t_; }

 private:
  struct Sample {
    int row;
    double t;
    std::vector<Eigen::Vector2d> p;
  };
  struct EntityState {
    bool moving = false;
    Eigen::Vector2d anchor = Eigen::Vector2d::Zero();  ///< rest position (running mean)
    int anchor_n = 0;
    /// Where it rests, nudges aside: where it first rested, where its last motion that
    /// was no nudge ended, or where the anchor has stayed for pause_s (a nudge not put
    /// back).
    Eigen::Vector2d home = Eigen::Vector2d::Zero();
    /// Where it came to rest (first, or at the end of its last motion): the anchor follows
    /// a creep no farther than start_m from here.
    Eigen::Vector2d rest_from = Eigen::Vector2d::Zero();
    double anchor_t = 0;  ///< when the anchor was last set
    Motion motion;
  };
  void startMotion(size_t e);
  /// True when entity e's last still_s of rows stay within `within` of their mean, `rest`.
  bool stillAt(size_t e, double within, Eigen::Vector2d& rest) const;
  /// When entity e has rested for still_s: its rest position and the history index of
  /// the first row at rest.
  bool stopped(size_t e, Eigen::Vector2d& rest, size_t& first) const;
  void endMotion(size_t e, const Eigen::Vector2d& rest, size_t first);
  /// The time entity e left (reached) `rest`, extrapolated from history rows from..to.
  std::optional<double> restTime(size_t from, size_t to, size_t e, const Eigen::Vector2d& rest) const;
  /// Updates m.max_distance with history row i (rows with a held pose left out).
  void trackDistances(Motion& m, size_t i) const;
  /// Entity e's speed at history index i, m/s, over the rows of the last still_s / 2.
  double speed(size_t i, size_t e) const;
  /// Entity e's position at history index i, averaged over 5 rows (fewer at the ends).
  Eigen::Vector2d smoothed(size_t i, size_t e) const;

  SegmentationOptions o_;
  std::vector<EntityState> state_;
  std::deque<Sample> history_;  ///< the last history_s seconds of rows
  std::vector<Motion> done_;
  int row_ = 0;
  double last_t_ = 0;
  bool finished_ = false;
};

}  // namespace ddace::label
