// A synthetic overhead camera (a test helper): renders the table, its corner markers
// and the entities' markers as a pinhole camera above the table would see them, with
// perspective, blur, noise, changing light and occlusion by a "hand", so the real
// tracker can be tested end to end without hardware.
//
// Owns: rendering and the ground-truth camera geometry. Must not: decide where
// entities are (callers pass the true poses).
// Units: metres and radians in the table frame; pixels; seconds.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ddace/task/task_spec.h"
#include "ddace/vision/table_frame.h"
#include "ddace/vision/tracker.h"

namespace ddace::vision {

/// A hand over an entity from start_s to end_s (seconds since the camera's first frame).
struct Occlusion {
  std::string entity;
  double start_s = 0, end_s = 0;
};

struct SyntheticCameraConfig {
  int width = 1280, height = 720;       ///< pixels
  double hfov_deg = 65.0;               ///< horizontal field of view
  cv::Vec3d position{0.4, -0.02, 1.0};  ///< camera centre, table frame, metres
  cv::Point2d look_at{0.4, 0.3};        ///< table point on the optical axis
  double roll_deg = 0.0;                ///< rotation about the optical axis
  cv::Size2d table_size{0.8, 0.6};      ///< the working area, metres from table_origin
  cv::Point2d table_origin{0.0, 0.0};   ///< its corner nearest the origin (framedOnCorners sets it)
  double table_margin_m = 0.06;         ///< the white table top extends this far beyond it
  double blur_sigma_px = 0.7;           ///< Gaussian blur (defocus)
  double noise_sigma = 2.0;             ///< Gaussian pixel noise (grey levels)
  double light_amplitude = 0.15;        ///< brightness varies by +-this fraction ...
  double light_period_s = 5.0;          ///< ... with this period
  double light_gradient = 0.25;         ///< brightness falls by this fraction across the image
  std::vector<Occlusion> occlusions;
  unsigned seed = 1;  ///< noise seed
};

/// Reads the synthetic camera's YAML (test/data/vision/synthetic_camera.yaml documents
/// it). Throws ddace::Error with file:line:column.
SyntheticCameraConfig parseSyntheticCameraConfig(const std::string& text, const std::string& file);
SyntheticCameraConfig loadSyntheticCameraConfig(const std::string& path);

/// `config` moved onto the table the corner markers of `markers` span, for a simulated
/// table of any size: the camera frames that table as `config` frames its own table_size
/// (the same view: field, tilt and roll kept; position, look-at and height scaled about the
/// table's centre by the larger ratio of the sides), and the table top drawn is the
/// corners' extent. Unchanged when `markers` has no corners.
SyntheticCameraConfig framedOnCorners(SyntheticCameraConfig config, const MarkerConfig& markers);

/// One entity as the camera should see it.
struct TrueEntity {
  std::string name;
  PlanarPose pose;        ///< table frame; the marker is drawn at yaw - the marker's yaw_offset
  bool occluded = false;  ///< draw a hand over it (as well as the configured occlusions)
  /// Its body on the table (task.yaml's footprint): an obstacle is drawn as a dark disc of
  /// this radius under its marker, a flat print (a goal) as its marker alone. Unset: the
  /// default footprint of the marker's kind (task::footprint).
  std::optional<task::Footprint> footprint = std::nullopt;
};

class SyntheticCamera {
 public:
  /// Throws ddace::Error when the camera does not look down at the table.
  SyntheticCamera(SyntheticCameraConfig config, MarkerConfig markers);

  /// Renders a mono8 frame at `t_s` seconds since the first frame. Entities whose
  /// name is not in the marker configuration are not drawn.
  cv::Mat render(const std::vector<TrueEntity>& entities, double t_s);

  /// Intrinsics (no distortion).
  CameraModel camera() const;
  /// The true table frame (from the camera pose).
  TableFrame tableFrame() const;
  /// Pixel of a table-frame point.
  cv::Point2d project(const cv::Vec3d& table_point) const;
  const SyntheticCameraConfig& config() const { return config_; }
  bool occluded(const std::string& entity, double t_s) const;

 private:
  enum class MarkerPart { Whole, QuietZone, Square };
  void drawMarker(cv::Mat& img, int id, double size_m, const PlanarPose& pose, double height_m, MarkerPart part);
  void drawConvex(cv::Mat& img, const std::vector<cv::Vec3d>& corners, int grey);

  SyntheticCameraConfig config_;
  MarkerConfig markers_;
  DetectorConfig family_;
  cv::Matx33d K_, R_;
  cv::Vec3d t_;
  cv::Mat background_;  // table on the floor, before entities
  cv::Mat light_;       // CV_32F per-pixel gradient
  cv::RNG rng_;
};

}  // namespace ddace::vision
