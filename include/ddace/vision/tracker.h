// The overhead tracker: detection + table frame + per-entity filtering, one call per
// camera frame. ROS-free; tracker_node wraps it.
//
// Search strategy: a full-frame pass every `roi.full_frame_every` frames (and whenever
// the table frame is not known yet); in between, each marker seen
// within filter.hold is looked for where its pixel velocity predicts it (its box +
// roi.margin + filter.gate_margin), for markers of its size only (aruco: one threshold
// window matched to its edge). A marker missed there is looked for again at once, in
// the same frame: in the region of every position the pose filter would accept
// (filter.max_speed x the time since it was seen) with the detector's full search,
// then, for AprilTag, with libapriltag at full resolution. When the first looks would
// cover most of the image the whole frame is searched instead. A configured marker that
// no region follows (never seen yet, unseen for longer than filter.hold, or missing so
// long that its region would cover most of the image) is searched for in the same frame
// too, over the whole image but the markers found in it: dark quadrilaterals of its expected size in pixels (its edge x
// the pixels per metre of the tracked markers), found on an image reduced to about 12 px per marker edge, are read by
// the detector in a region around each. Corner markers are searched like the others (set roi.track_corners false to
// search them on full-frame passes only).
//
// Configuration comes from two commented YAML files: config/markers.yaml (which
// markers exist: family, corner markers, entity markers) and config/tracker.yaml
// (tuning). Both readers report errors as file:line:column.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "ddace/task/task_spec.h"
#include "ddace/vision/detector.h"
#include "ddace/vision/pose_filter.h"
#include "ddace/vision/table_frame.h"

namespace ddace::vision {

/// A marker that identifies one entity of the scene.
struct EntityMarker {
  int id = -1;
  std::string name;  ///< entity name as in task.yaml
  task::EntityKind kind = task::EntityKind::Robot;
  std::string type;             ///< free text, e.g. "hamster"
  double size_m = 0.03;         ///< edge of the outer black square
  double height_m = 0.0;        ///< marker height above the table
  double yaw_offset_rad = 0.0;  ///< entity yaw = marker yaw + offset
};

/// config/markers.yaml.
struct MarkerConfig {
  DetectorBackend backend = DetectorBackend::Aruco;
  std::string family = "DICT_4X4_50";
  std::vector<CornerMarker> corners;   ///< exactly four, or none (calibrated camera)
  double corner_size_m = 0.04;         ///< edge of the corner markers' black square
  std::vector<EntityMarker> entities;  ///< in scene order

  /// Entity marker with this id, or nullptr.
  const EntityMarker* entityById(int id) const;
  bool isCorner(int id) const;
};

struct RoiConfig {
  bool enabled = true;
  int full_frame_every = 15;  ///< frames between full-frame passes (>= 1; 1 = always full)
  double margin = 0.6;        ///< region = marker box grown by margin * marker edge on every side
  int min_margin_px = 12;     ///< ... but at least this many pixels
  bool track_corners = true;  ///< also search the corner markers between full-frame passes
                              ///< (false: the table frame is re-estimated on full-frame passes only)
  // Regions grow at FilterConfig::max_speed_mps: one parameter for "how fast can a
  // marker move", so the search never loses what the filter would accept.
};

/// The table frame from the corner markers.
struct TableConfig {
  double max_reprojection_px = 1.5;  ///< a fit whose largest reprojection error exceeds this is refused
  double smoothing = 0.2;            ///< per-frame gain of the corner markers' image positions
                                     ///< (1 = the last frame only); reset when one jumps by
                                     ///< more than max_reprojection_px (the camera moved)
};

/// config/tracker.yaml (plus the markers).
struct TrackerConfig {
  MarkerConfig markers;
  DetectorConfig detector;  ///< backend/family copied from markers; tuning from tracker.yaml
  RoiConfig roi;
  FilterConfig filter;
  TableConfig table;
};

/// Whether raised markers are corrected for parallax (needs intrinsics). Never
/// switched off silently: FrameResult says which and why.
enum class HeightCorrection {
  On,                  ///< intrinsics given and consistent with the table frame
  NoIntrinsics,        ///< no camera_info / calibration file: errors of height / camera height x distance
  IntrinsicsDoNotFit,  ///< intrinsics given but the table frame contradicts them (wrong file?)
};
/// "on", "off: no intrinsics", "off: the intrinsics do not fit the table frame".
std::string heightCorrectionName(HeightCorrection state);

/// Parses markers.yaml text; `file` names it in diagnostics. Throws ddace::Error
/// listing every problem as file:line:column (unknown keys, duplicate ids or names,
/// ids outside the family, names that task.yaml would refuse, not four corners, ...).
MarkerConfig parseMarkerConfig(const std::string& text, const std::string& file);
MarkerConfig loadMarkerConfig(const std::string& path);
/// Throws ddace::Error when `markers` (read from `markers_file`) has no marker for an entity
/// of `task` (read from `task_file`), or has it as another kind: the tracker would never
/// report that entity, and a run on the table would wait for it. Markers of entities the
/// task does not have are allowed (tracked, unused).
void requireTaskEntities(const MarkerConfig& markers, const std::string& markers_file, const task::TaskSpec& task,
                         const std::string& task_file);
/// Parses tracker.yaml text into `config` (markers untouched). Throws ddace::Error.
void parseTrackerTuning(const std::string& text, const std::string& file, TrackerConfig& config);
/// Loads both files into one TrackerConfig. Throws ddace::Error.
TrackerConfig loadTrackerConfig(const std::string& markers_path, const std::string& tracker_path);

/// What the tracker knows about one entity after a frame.
struct EntityState {
  std::string name;
  task::EntityKind kind = task::EntityKind::Robot;
  PlanarPose pose;       ///< table frame; held while not visible
  bool visible = false;  ///< measured (and accepted) in this frame
  bool stale = true;     ///< never seen, not seen for longer than filter.hold_s, or held
                         ///< while its speed says it may have moved more than
                         ///< filter.max_drift: never publish it as a current pose. A goal
                         ///< (a print fixed to the table) once seen is never stale: hidden
                         ///< under robots parked on it, it keeps its last pose
  double last_seen = 0;  ///< stamp of the last accepted measurement, seconds
  double drift_m = 0;    ///< speed estimate x time since last seen (0 while visible)
};

struct FrameResult {
  double stamp = 0;
  bool full_frame = false;            ///< this frame was searched whole
  std::vector<cv::Rect> rois;         ///< searched regions: first looks, then the wider second
                                      ///< regions of markers missed in them, then the candidates
                                      ///< read for absent markers (empty for a full frame)
  int first_look_misses = 0;          ///< tracked markers not found where expected (first look),
                                      ///< searched again at once
  int absent = 0;                     ///< configured markers the regions do not follow (never
                                      ///< seen, unseen for longer than filter.hold, or missing
                                      ///< so long that their region would cover most of the
                                      ///< image), searched for over the rest of the image
                                      ///< (region frames only; a full frame searches them all)
  int absent_candidates = 0;          ///< regions of marker-sized quadrilaterals read for them
  bool second_look = false;           ///< a marker missed where expected was looked for again
                                      ///< with the second-look detector
  std::vector<Detection> detections;  ///< every configured marker found, raw image pixels
  bool table_valid = false;           ///< a table frame is known
  bool table_updated = false;         ///< re-estimated from the corner markers in this frame
  /// Largest reprojection error of this frame's corner-marker fit (pixels); -1 when no fit
  /// was made (not all four seen, fixed table frame).
  double table_reprojection_px = -1;
  bool table_refused = false;  ///< this frame's fit exceeded table.max_reprojection_px (the
                               ///< previous table frame, if any, is kept)
  HeightCorrection height_correction = HeightCorrection::NoIntrinsics;
  std::vector<EntityState> entities;  ///< in MarkerConfig::entities order
};

class Tracker {
 public:
  /// Throws ddace::Error for an unusable configuration (unknown family, ...).
  explicit Tracker(TrackerConfig config);
  ~Tracker();

  /// Intrinsics and distortion (camera_info or a calibration file). Enables
  /// undistortion and marker height correction. Frames of another size than
  /// camera.image_size (when set) are refused by process().
  void setCamera(const CameraModel& camera);
  bool hasCamera() const { return camera_.valid; }
  HeightCorrection heightCorrection() const;
  /// Without intrinsics: the largest position error raised markers get (the highest
  /// configured marker, over the corner markers' area), from the table frame and the
  /// last image size. nullopt before the first table frame or with intrinsics.
  std::optional<ParallaxEstimate> parallaxWithoutIntrinsics() const;
  /// Uses a fixed table frame (calibrated camera) instead of the corner markers.
  void setFixedTableFrame(const TableFrame& frame);

  /// Processes one frame (8-bit grey or BGR) taken at `stamp` seconds.
  FrameResult process(const cv::Mat& image, double stamp);

  const TrackerConfig& config() const { return config_; }
  const std::optional<TableFrame>& tableFrame() const { return table_; }
  /// Current states (same as the last FrameResult::entities).
  std::vector<EntityState> states(double stamp) const;
  long frames() const { return frames_; }

 private:
  /// How far from its prediction a search region reaches.
  enum class Reach {
    Predicted,  ///< the predicted box + filter.gate_margin (the first look)
    MaxSpeed,   ///< + filter.max_speed x the time since it was seen, last box included
  };
  /// A search region and the edge of the markers expected in it (pixels).
  struct Region {
    cv::Rect rect;
    double side_px = 0;
  };
  /// Merged search regions around the markers `ids` that were seen within filter.hold.
  std::vector<Region> regions(const cv::Size& size, double stamp, Reach reach, const std::set<int>& ids) const;
  /// Markers seen within filter.hold that this frame must search (corner markers only
  /// on full frames when roi.track_corners is false).
  std::set<int> trackedIds(bool full_frame) const;
  /// Configured markers the regions do not follow (never seen, or unseen for longer than
  /// filter.hold), less those in `found`.
  std::set<int> absentIds(const std::set<int>& found) const;
  /// The edge in pixels expected of marker `id`: its size x the median pixels per metre of
  /// the tracked markers (0 when none is tracked).
  double expectedSidePx(int id) const;
  /// Regions around the dark quadrilaterals with edges of side_min..side_max pixels
  /// (perspective and rotation allowed for) whose centres lie outside `covered`.
  std::vector<Region> quadCandidates(double side_min, double side_max, const std::vector<cv::Rect>& covered);
  /// Re-fits the table frame when all corner markers are among `undistorted`.
  void updateTable(const std::vector<Detection>& undistorted, FrameResult& result);
  /// The image as 8-bit mono in gray_, checked against the calibration's image size.
  void toGray(const cv::Mat& image);
  /// The detections of one frame and where it looked (tracker.cpp).
  struct FrameSearch;
  /// Looks where the tracked markers are predicted (or the whole frame), then again for
  /// those missing there. Returns the markers whose regions would cover most of the image.
  std::set<int> lookWhereExpected(FrameSearch& s, double stamp);
  /// Looks for the configured markers the regions do not follow, in marker-sized quads.
  void lookForAbsent(FrameSearch& s, const std::set<int>& unfollowed);
  /// Keeps one detection per configured marker (the nearest its last position) in
  /// result.detections and updates where and how fast each was last seen.
  void keepConfigured(const std::vector<Detection>& found, double stamp, FrameResult& result);
  /// Undistorts the detections, re-fits the table, and feeds the entities' pose filters.
  void updateEntities(double stamp, FrameResult& result);

  TrackerConfig config_;
  std::unique_ptr<FiducialDetector> detector_;
  std::unique_ptr<FiducialDetector> second_look_;  // for markers missed where expected
  CameraModel camera_;
  std::optional<TableFrame> table_;
  bool fixed_table_ = false;
  std::vector<PoseFilter> filters_;
  std::map<int, Detection> last_seen_px_;    // id -> last raw detection (region search)
  std::map<int, double> last_seen_t_;        // id -> stamp of that detection
  std::map<int, cv::Point2d> velocity_px_;   // id -> pixel velocity from its last two detections, px/s
  std::map<int, Detection> corner_average_;  // corner marker id -> smoothed undistorted detection
  cv::Size image_size_;
  long frames_ = 0;
  cv::Mat gray_;
  cv::Mat small_, binary_;  // the reduced image and its threshold (quadCandidates)
};

/// How the tracker is doing, from its last frame (the tracker node's diagnostics).
struct TrackerStatus {
  enum class Level { Ok, Warn, Error };
  Level level = Level::Warn;
  std::string summary;  ///< one line for the operator
  int visible = 0;      ///< entities seen in the last frame
  int stale = 0;        ///< entities too long unseen to be trusted
};

/// ERROR without a table frame (refused fit or not all corner markers seen); WARN
/// without height correction (with `parallax`'s worst error in mm when known), with a
/// refused fit while an older table frame is kept, or before the first frame (`last`
/// empty); OK otherwise. `max_reprojection_px`: table.max_reprojection_px.
TrackerStatus trackerStatus(const std::optional<FrameResult>& last, const std::optional<ParallaxEstimate>& parallax,
                            double max_reprojection_px);

/// "table frame refused: reprojection error E px > table.max_reprojection_px M (...)".
std::string tableRefusedText(const FrameResult& result, double max_reprojection_px);

/// Stamps for the frames of a recorded video file: the file's own time line (its frame
/// times), anchored at the time the first frame was read, so the intervals between
/// frames stay as recorded whatever the playback rate. Seconds on any clock.
class VideoTimeline {
 public:
  /// The stamp of the frame `file_s` seconds into the file, read at `now_s`.
  double stamp(double file_s, double now_s) {
    if (!start_s_) start_s_ = now_s - file_s;
    return *start_s_ + file_s;
  }

 private:
  std::optional<double> start_s_;
};

/// Merges overlapping rectangles into their bounding box wherever that box is at most
/// 1.5 times their areas together (overlaps may remain; a marker is then searched twice).
std::vector<cv::Rect> mergeRegions(std::vector<cv::Rect> rects);

}  // namespace ddace::vision
