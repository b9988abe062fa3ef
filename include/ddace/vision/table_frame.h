// The table frame and planar poses of markers on it.
//
// The table frame (`table`): origin at a table corner, x along one edge, y along the
// other, z up (REP-103), metres. A top-down camera sees the table plane through a
// homography; a robot's marker gives its x, y and yaw only, from the marker's corners
// mapped into the plane (never a 3-D pose: those flip for a marker facing the camera).
//
// Two ways to get the homography: from four corner markers at known table positions
// (re-estimated whenever all four are seen, checked by its reprojection error), or
// from a calibrated camera and the pose of the table plane in the camera frame.
//
// Owns: image <-> table mapping, undistortion, marker height (parallax) correction.
// Must not: detect markers or filter poses.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ddace/common/angle.h"
#include "ddace/vision/detector.h"

namespace ddace::vision {

/// Pinhole intrinsics and distortion (as in sensor_msgs/CameraInfo: K, D plumb_bob).
struct CameraModel {
  cv::Matx33d K = cv::Matx33d::eye();
  std::vector<double> D;  ///< k1 k2 p1 p2 [k3 ...]; empty = no distortion
  bool valid = false;     ///< false: intrinsics unknown (homography-only mode)
  cv::Size image_size;    ///< the calibrated image size; 0 x 0 = not known (any size accepted)

  /// Removes lens distortion: returns the pixel an ideal pinhole camera with the same
  /// K would see. Identity when D is empty or the model is not valid.
  std::vector<cv::Point2f> undistort(const std::vector<cv::Point2f>& px) const;
};

/// x, y in metres and yaw in radians (counter-clockwise from table +x, in (-pi, pi]).
struct PlanarPose {
  double x = 0, y = 0, yaw = 0;
};

/// A corner marker: its id and where its centre lies on the table.
struct CornerMarker {
  int id = -1;
  cv::Point2d table_xy;  ///< metres, table frame
};

struct TableFit;

class TableFrame {
 public:
  /// Least-squares homography from the 4 centres and 16 corners of the corner markers
  /// (undistorted pixels) to the table, with its reprojection error. `corner_size_m`
  /// is the edge of their black squares.
  static TableFit fitCornerMarkers(const std::vector<Detection>& detections, const std::vector<CornerMarker>& corners,
                                   double corner_size_m);
  /// Homography from the centres of four corner markers (undistorted pixels) to their
  /// table positions. nullopt unless all four are among `detections` and they are in
  /// general position (no three collinear in the image).
  static std::optional<TableFrame> fromCornerMarkers(const std::vector<Detection>& detections,
                                                     const std::vector<CornerMarker>& corners);
  /// From intrinsics and the pose of the table frame in the camera frame
  /// (X_cam = R * X_table + t, metres). Throws ddace::Error when the table plane is
  /// behind the camera or K is singular.
  static TableFrame fromCameraPose(const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t);
  /// The same from [x y z roll pitch yaw] (metres, radians; R = Rz(yaw) Ry(pitch) Rx(roll)),
  /// the form of tracker_node's ~table_in_camera. Throws ddace::Error naming `what`
  /// unless there are 6 finite numbers.
  static TableFrame fromCameraPose(const cv::Matx33d& K, const std::vector<double>& xyz_rpy, const std::string& what);

  /// Table point (metres, on the plane z = 0) of an undistorted pixel.
  cv::Point2d imageToTable(const cv::Point2d& px) const;
  /// Undistorted pixel of a table point (z = 0).
  cv::Point2d tableToImage(const cv::Point2d& xy) const;

  /// Recovers the camera centre in the table frame from the homography and K (needed
  /// for marker height correction). False when K gives no consistent rotation.
  bool setIntrinsics(const cv::Matx33d& K);
  /// Camera centre in the table frame (metres) when known (setIntrinsics or fromCameraPose).
  std::optional<cv::Vec3d> cameraCenter() const { return camera_center_; }

  /// Planar pose of a marker whose corners are undistorted pixels (Detection order).
  /// yaw is the direction of the marker's "right" edge (corner 0 -> 1, i.e. printed +x).
  /// `height_m` is the marker's height above the table: with a known camera centre the
  /// position is corrected for parallax; without, the error is height/camera height
  /// times the distance from the camera's nadir.
  PlanarPose markerPose(const Detection& undistorted, double height_m = 0.0) const;

  const cv::Matx33d& imageToTableHomography() const { return H_; }

 private:
  cv::Matx33d H_ = cv::Matx33d::eye();     // undistorted pixel -> table (metres)
  cv::Matx33d Hinv_ = cv::Matx33d::eye();  // table -> pixel
  std::optional<cv::Vec3d> camera_center_;
};

/// A table frame fitted to the four corner markers, and how well it fits.
struct TableFit {
  std::optional<TableFrame> frame;  ///< nullopt: not all four seen, or degenerate
  /// Largest distance (undistorted pixels) between the 20 detected points (4 centres, 16
  /// square corners) and the same points of the fitted model: the centres at their
  /// configured table positions, each square of edge corner_size_m around its centre.
  /// Large when a configured position or corner_size is wrong or a corner misdetected.
  double reprojection_px = 0;
};

/// What raised markers cost without intrinsics: without them the tracker cannot
/// correct parallax, and a marker `height_m` above the table appears shifted away from
/// the camera's nadir by height / camera height x its distance from the nadir.
struct ParallaxEstimate {
  double max_error_m = 0;      ///< largest shift over the working area (the corner markers' hull)
  double camera_height_m = 0;  ///< estimated camera height above the table
  double focal_px = 0;         ///< focal length used
  bool focal_assumed = false;  ///< true: the homography could not give the focal length
                               ///< (camera looking straight down), a 60 deg field of view was assumed
};

/// Estimates the camera from a homography alone (principal point at the image
/// centre, square pixels: the focal length follows from the table's axes being
/// perpendicular) and the shift of a marker `height_m` up at the worst point of `area`
/// (table points, metres). nullopt when no consistent camera fits.
std::optional<ParallaxEstimate> estimateParallaxWithoutIntrinsics(const TableFrame& frame, const cv::Size& image,
                                                                  double height_m,
                                                                  const std::vector<cv::Point2d>& area);

/// Wraps an angle into (-pi, pi] (the one definition is in common/angle.h).
using ddace::wrapAngle;

}  // namespace ddace::vision
