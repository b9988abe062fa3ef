// The overhead tracker: detection + table frame + per-entity filtering, one call per
// camera frame. ROS-free; tracker_node wraps it.
//
// Search strategy: a full-frame pass every `roi.full_frame_every` frames (and whenever
// the table frame is not known yet); in between, only regions around the last
// pixel position of every known marker (corner markers included) are searched.
// The region of a marker that is not found grows with the time since it was last seen
// (a robot under a hand drives on); a marker that left its region anyway is found
// again at the next full-frame pass. Corner
// markers are searched like the others (set roi.track_corners false to search them on
// full-frame passes only). With a decimating AprilTag detector, a marker missing
// near its last position is looked for again there at full resolution.
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
  std::string name;                             ///< entity name as in task.yaml
  task::EntityKind kind = task::EntityKind::Robot;
  std::string type;                             ///< free text, e.g. "hamster"
  double size_m = 0.03;                         ///< edge of the outer black square
  double height_m = 0.0;                        ///< marker height above the table
  double yaw_offset_rad = 0.0;                  ///< entity yaw = marker yaw + offset
};

/// config/markers.yaml.
struct MarkerConfig {
  std::string backend = "aruco";       ///< "aruco" or "apriltag"
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
  double lost_growth_mps = 0.3;  ///< the region of a marker not seen grows by this speed
                                 ///< times the time since it was last seen
};

/// config/tracker.yaml (plus the markers).
struct TrackerConfig {
  MarkerConfig markers;
  DetectorConfig detector;  ///< backend/family copied from markers; tuning from tracker.yaml
  RoiConfig roi;
  FilterConfig filter;
};

/// Parses markers.yaml text; `file` names it in diagnostics. Throws ddace::Error
/// listing every problem as file:line:column (unknown keys, duplicate ids or names,
/// ids outside the family, names that task.yaml would refuse, not four corners, ...).
MarkerConfig parseMarkerConfig(const std::string& text, const std::string& file);
MarkerConfig loadMarkerConfig(const std::string& path);
/// Parses tracker.yaml text into `config` (markers untouched). Throws ddace::Error.
void parseTrackerTuning(const std::string& text, const std::string& file, TrackerConfig& config);
/// Loads both files into one TrackerConfig. Throws ddace::Error.
TrackerConfig loadTrackerConfig(const std::string& markers_path, const std::string& tracker_path);

/// What the tracker knows about one entity after a frame.
struct EntityState {
  std::string name;
  task::EntityKind kind = task::EntityKind::Robot;
  PlanarPose pose;        ///< table frame; held while not visible
  bool visible = false;   ///< measured (and accepted) in this frame
  bool stale = true;      ///< never seen, or not seen for longer than filter.hold_s
  double last_seen = 0;   ///< stamp of the last accepted measurement, seconds
};

struct FrameResult {
  double stamp = 0;
  bool full_frame = false;           ///< this frame was searched whole
  std::vector<cv::Rect> rois;        ///< searched regions (empty for a full frame)
  std::vector<Detection> detections; ///< every configured marker found, raw image pixels
  bool table_valid = false;          ///< a table frame is known
  bool table_updated = false;        ///< re-estimated from the corner markers in this frame
  std::vector<EntityState> entities; ///< in MarkerConfig::entities order
};

class Tracker {
 public:
  /// Throws ddace::Error for an unusable configuration (unknown family, ...).
  explicit Tracker(TrackerConfig config);
  ~Tracker();

  /// Intrinsics and distortion (from camera_info). Enables undistortion and marker
  /// height correction.
  void setCamera(const CameraModel& camera);
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
  /// Search regions around the last positions (of the ids in `only`, when given).
  std::vector<cv::Rect> regions(const cv::Size& size, double stamp, const std::set<int>* only = nullptr) const;

  TrackerConfig config_;
  std::unique_ptr<FiducialDetector> detector_;
  std::unique_ptr<FiducialDetector> fine_detector_;  // AprilTag without decimation, for misses
  CameraModel camera_;
  std::optional<TableFrame> table_;
  bool fixed_table_ = false;
  std::vector<PoseFilter> filters_;
  std::map<int, Detection> last_seen_px_;  // id -> last raw detection (region search)
  std::map<int, double> last_seen_t_;      // id -> stamp of that detection
  double previous_stamp_ = 0;              // stamp of the previous frame
  long frames_ = 0;
  cv::Mat gray_;
};

/// Merges overlapping rectangles until none overlap (the union of each cluster).
std::vector<cv::Rect> mergeRegions(std::vector<cv::Rect> rects);

}  // namespace ddace::vision
