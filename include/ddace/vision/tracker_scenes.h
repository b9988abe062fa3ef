// The tracker's benchmark scenes (a test helper, like synthetic_camera.h): the frames
// bench_vision_track measures and test_tracker checks, so the two always see the same
// table. 1280x720 synthetic camera, tilted 9 degrees and rolled 3, blur and noise.
//
// - Small: 4 corner markers and 12 robots with 3 cm markers on slow circles (<= 0.09 m/s),
//   40 % light gradient across the image.
// - Fast: the same and a 3 cm ball passed back and forth across the table at 0.8 m/s.
// - Edge: 4 corner markers and 10 robots along the table's edges, near the image's
//   borders, under a 40 % radial light falloff toward the edges (vignetting: brightness
//   1 - 0.4 (r / r_table)^2, r from the image's centre, r_table that of the working
//   area's furthest corner; applied before the noise); one robot ("R1") starts in the
//   darkest corner, between the table's edge and a corner marker, and drives into the
//   middle and back.
//
// Units: metres and radians in the table frame; seconds since the first frame.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ddace/vision/synthetic_camera.h"
#include "ddace/vision/tracker.h"

namespace ddace::vision {

enum class TrackerScene { Small, Fast, Edge };
/// "small", "fast", "edge".
std::string toString(TrackerScene scene);

class TrackerSceneRenderer {
 public:
  /// The scene's markers for `backend` (aruco DICT_4X4_50 or AprilTag tag36h11).
  TrackerSceneRenderer(TrackerScene scene, DetectorBackend backend);

  const MarkerConfig& markers() const { return markers_; }
  /// Intrinsics for the tracker (no distortion).
  CameraModel camera() const { return camera_->camera(); }
  /// The true table frame (from the camera's pose).
  TableFrame tableFrame() const { return camera_->tableFrame(); }
  /// The true poses at `t_s` (in markers().entities order).
  std::vector<TrueEntity> truth(double t_s) const;
  /// The mono8 frame of `truth` at `t_s`.
  cv::Mat render(const std::vector<TrueEntity>& truth, double t_s);

 private:
  TrackerScene scene_;
  MarkerConfig markers_;
  std::unique_ptr<SyntheticCamera> camera_;
  cv::Mat falloff_;  // CV_32F brightness factor per pixel (Edge), empty otherwise
  double noise_sigma_ = 0;
  cv::RNG rng_{7};
};

/// The reference every tracker measurement is compared with: OpenCV's aruco detector
/// with its default parameters on the whole frame (for tag36h11 its DICT_APRILTAG_36h11,
/// which reads the same prints). Returns what it found, corners as OpenCV reports them
/// (the centre does not depend on their order).
std::vector<Detection> referenceDetect(const cv::Mat& gray, DetectorBackend backend);

}  // namespace ddace::vision
