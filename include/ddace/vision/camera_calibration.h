// Camera intrinsics from a calibration file in the camera_info YAML format that the
// ROS camera calibration tools write (camera_calibration's "Save", or
// camera_calibration_parsers):
//
//   image_width: 1280
//   image_height: 720
//   camera_name: overhead
//   camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
//   distortion_model: plumb_bob          # or rational_polynomial
//   distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
//   rectification_matrix: {rows: 3, cols: 3, data: [...]}    # optional
//   projection_matrix: {rows: 3, cols: 4, data: [...]}       # optional
//
// Owns: reading and checking that file (every error as file:line:column).
// Must not: open cameras or know about ROS.
// Units: pixels.
#pragma once

#include <string>

#include "ddace/vision/table_frame.h"

namespace ddace::vision {

struct CameraCalibration {
  std::string camera_name;
  std::string distortion_model;  ///< "plumb_bob" or "rational_polynomial" (what undistortion supports)
  CameraModel camera;            ///< K, D, image size; valid
};

/// Parses the file's text; `file` names it in errors. Throws ddace::Error listing
/// every problem (missing or unknown keys, rows x cols not matching data, a singular
/// camera matrix, a distortion model undistortion cannot apply, ...).
CameraCalibration parseCameraCalibration(const std::string& text, const std::string& file);
CameraCalibration loadCameraCalibration(const std::string& path);

}  // namespace ddace::vision
