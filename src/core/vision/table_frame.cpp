#include "ddace/vision/table_frame.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "ddace/common/error.h"

namespace ddace::vision {

std::vector<cv::Point2f> CameraModel::undistort(const std::vector<cv::Point2f>& px) const {
  if (!valid || D.empty() || px.empty()) return px;
  bool any = false;
  for (double d : D) any = any || d != 0.0;
  if (!any) return px;
  std::vector<cv::Point2f> out;
  cv::undistortPoints(px, out, cv::Mat(K), cv::Mat(D), cv::noArray(), cv::Mat(K));
  return out;
}

namespace {

cv::Point2d apply(const cv::Matx33d& H, const cv::Point2d& p) {
  const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
  return {v[0] / v[2], v[1] / v[2]};
}

double cross(const cv::Point2f& a, const cv::Point2f& b, const cv::Point2f& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

}  // namespace

std::optional<TableFrame> TableFrame::fromCornerMarkers(const std::vector<Detection>& detections,
                                                        const std::vector<CornerMarker>& corners) {
  if (corners.size() != 4) return std::nullopt;
  std::vector<cv::Point2f> img, table;
  for (const auto& c : corners) {
    const Detection* found = nullptr;
    for (const auto& d : detections)
      if (d.id == c.id) found = &d;
    if (!found) return std::nullopt;
    img.push_back(found->center());
    table.emplace_back(static_cast<float>(c.table_xy.x), static_cast<float>(c.table_xy.y));
  }
  // Degenerate when three centres are (nearly) collinear: the homography is meaningless.
  for (int i = 0; i < 4; ++i) {
    const double area = std::abs(cross(img[i], img[(i + 1) % 4], img[(i + 2) % 4]));
    if (area < 100.0) return std::nullopt;
  }
  const cv::Mat H = cv::getPerspectiveTransform(img, table);
  if (H.empty()) return std::nullopt;
  TableFrame f;
  f.H_ = cv::Matx33d(H);
  f.Hinv_ = f.H_.inv();
  return f;
}

TableFit TableFrame::fitCornerMarkers(const std::vector<Detection>& detections,
                                      const std::vector<CornerMarker>& corners, double corner_size_m) {
  TableFit fit;
  const auto exact = fromCornerMarkers(detections, corners);
  if (!exact) return fit;
  // Model points: each marker's centre at its configured place and its square's
  // corners around it, turned as the exact fit sees it (printed TL, TR, BR, BL).
  std::vector<cv::Point2f> img, table;
  const double h = corner_size_m / 2;
  const double local[4][2] = {{-h, h}, {h, h}, {h, -h}, {-h, -h}};
  for (const auto& c : corners) {
    const Detection* d = nullptr;
    for (const auto& det : detections)
      if (det.id == c.id) d = &det;
    const double yaw = exact->markerPose(*d).yaw, cy = std::cos(yaw), sy = std::sin(yaw);
    img.push_back(d->center());
    table.emplace_back(static_cast<float>(c.table_xy.x), static_cast<float>(c.table_xy.y));
    for (int k = 0; k < 4; ++k) {
      img.push_back(d->corners[k]);
      table.emplace_back(static_cast<float>(c.table_xy.x + cy * local[k][0] - sy * local[k][1]),
                         static_cast<float>(c.table_xy.y + sy * local[k][0] + cy * local[k][1]));
    }
  }
  // Least squares in the image (where the detection noise is): table -> pixel.
  const cv::Mat Hinv = cv::findHomography(table, img, 0);
  if (Hinv.empty()) return fit;
  TableFrame f;
  f.Hinv_ = cv::Matx33d(Hinv);
  f.H_ = f.Hinv_.inv();
  for (size_t i = 0; i < img.size(); ++i) {
    const cv::Point2d p = f.tableToImage(table[i]);
    fit.reprojection_px = std::max(fit.reprojection_px, std::hypot(p.x - img[i].x, p.y - img[i].y));
  }
  fit.frame = f;
  return fit;
}

TableFrame TableFrame::fromCameraPose(const cv::Matx33d& K, const std::vector<double>& v, const std::string& what) {
  bool finite = v.size() == 6;
  for (double x : v) finite = finite && std::isfinite(x);
  if (!finite) throw Error(what + " needs 6 finite numbers [x y z roll pitch yaw] (metres, radians)");
  const double r = v[3], p = v[4], y = v[5];
  const cv::Matx33d Rx(1, 0, 0, 0, std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r));
  const cv::Matx33d Ry(std::cos(p), 0, std::sin(p), 0, 1, 0, -std::sin(p), 0, std::cos(p));
  const cv::Matx33d Rz(std::cos(y), -std::sin(y), 0, std::sin(y), std::cos(y), 0, 0, 0, 1);
  try {
    return fromCameraPose(K, Rz * Ry * Rx, cv::Vec3d(v[0], v[1], v[2]));
  } catch (const Error& e) {
    throw Error(what + ": " + e.what());
  }
}

std::optional<ParallaxEstimate> estimateParallaxWithoutIntrinsics(const TableFrame& frame, const cv::Size& image,
                                                                  double height_m,
                                                                  const std::vector<cv::Point2d>& area) {
  if (image.width <= 0 || image.height <= 0 || area.empty()) return std::nullopt;
  // table -> pixel = K [r1 r2 t] up to scale; with the principal point removed the
  // columns a1, a2 satisfy (a1.xy . a2.xy) / f^2 + a1.z a2.z = 0 (r1 _|_ r2) and
  // (|a1.xy|^2 - |a2.xy|^2) / f^2 + a1.z^2 - a2.z^2 = 0 (|r1| = |r2|).
  const double cx = (image.width - 1) / 2.0, cy = (image.height - 1) / 2.0;
  const cv::Matx33d T(1, 0, -cx, 0, 1, -cy, 0, 0, 1);
  const cv::Matx33d A = T * frame.imageToTableHomography().inv();
  const cv::Vec3d a1(A(0, 0), A(1, 0), A(2, 0)), a2(A(0, 1), A(1, 1), A(2, 1));
  const double scale = std::max(cv::norm(a1), cv::norm(a2));
  std::vector<double> f2;
  const double d1 = a1[2] * a2[2], d2 = a1[2] * a1[2] - a2[2] * a2[2];
  // Each equation only when its perspective terms are not lost in rounding.
  if (std::abs(d1) > 1e-9 * scale * scale) f2.push_back(-(a1[0] * a2[0] + a1[1] * a2[1]) / d1);
  if (std::abs(d2) > 1e-9 * scale * scale)
    f2.push_back(-(a1[0] * a1[0] + a1[1] * a1[1] - a2[0] * a2[0] - a2[1] * a2[1]) / d2);
  ParallaxEstimate est;
  for (double v : f2)
    if (v > 0 && std::sqrt(v) > 0.2 * image.width && std::sqrt(v) < 20.0 * image.width) {
      est.focal_px = std::sqrt(v);
      break;
    }
  if (est.focal_px == 0) {
    est.focal_px = image.width / (2 * std::tan(30.0 * M_PI / 180));
    est.focal_assumed = true;
  }
  TableFrame f = frame;
  if (!f.setIntrinsics(cv::Matx33d(est.focal_px, 0, cx, 0, est.focal_px, cy, 0, 0, 1))) return std::nullopt;
  const cv::Vec3d C = *f.cameraCenter();
  est.camera_height_m = C[2];
  for (const auto& p : area)
    est.max_error_m = std::max(est.max_error_m, height_m / C[2] * std::hypot(p.x - C[0], p.y - C[1]));
  return est;
}

TableFrame TableFrame::fromCameraPose(const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t) {
  if (std::abs(cv::determinant(K)) < 1e-12) throw Error("camera matrix K is singular");
  // A table point (x, y, 0) projects as K [r1 r2 t] (x, y, 1).
  cv::Matx33d M;
  for (int r = 0; r < 3; ++r) {
    M(r, 0) = R(r, 0);
    M(r, 1) = R(r, 1);
    M(r, 2) = t[r];
  }
  const cv::Vec3d center = -(R.t() * t);
  if (center[2] <= 0) throw Error("the camera is not above the table plane (camera z <= 0 in the table frame)");
  // The optical axis in table coordinates is R's third row: it must point down.
  if (R(2, 2) >= 0) throw Error("the camera does not look down at the table (optical axis z >= 0 in the table frame)");
  TableFrame f;
  f.Hinv_ = K * M;
  f.H_ = f.Hinv_.inv();
  f.camera_center_ = center;
  return f;
}

bool TableFrame::setIntrinsics(const cv::Matx33d& K) {
  // Hinv ~ K [r1 r2 t]: undo K, normalise by the columns' length, re-orthogonalise.
  cv::Matx33d M = K.inv() * Hinv_;
  const cv::Vec3d m1(M(0, 0), M(1, 0), M(2, 0)), m2(M(0, 1), M(1, 1), M(2, 1)), m3(M(0, 2), M(1, 2), M(2, 2));
  const double n1 = cv::norm(m1), n2 = cv::norm(m2);
  if (n1 < 1e-12 || n2 < 1e-12) return false;
  double s = 2.0 / (n1 + n2);
  if (m3[2] * s < 0) s = -s;  // the table lies in front of the camera (t.z > 0)
  const cv::Vec3d r1 = m1 * s, r2 = m2 * s, t = m3 * s;
  // K does not fit this homography: the table's axes must come out of equal length
  // and perpendicular (the right K gives both within 0.1 %, a focal length 2.5 times
  // too long an 11 % length difference on a camera tilted 13 degrees).
  if (std::abs(n1 - n2) / std::max(n1, n2) > 0.05) return false;
  if (std::abs(m1.dot(m2)) / (n1 * n2) > 0.05) return false;
  cv::Matx33d R;
  const cv::Vec3d r3 = r1.cross(r2);
  for (int r = 0; r < 3; ++r) {
    R(r, 0) = r1[r];
    R(r, 1) = r2[r];
    R(r, 2) = r3[r];
  }
  const cv::SVD svd{cv::Mat(R)};
  const cv::Matx33d Rn{cv::Mat(svd.u * svd.vt)};
  cv::Vec3d center = -(Rn.t() * t);
  if (center[2] <= 0) return false;
  camera_center_ = center;
  return true;
}

cv::Point2d TableFrame::imageToTable(const cv::Point2d& px) const {
  return apply(H_, px);
}
cv::Point2d TableFrame::tableToImage(const cv::Point2d& xy) const {
  return apply(Hinv_, xy);
}

PlanarPose TableFrame::markerPose(const Detection& d, double height_m) const {
  std::array<cv::Point2d, 4> c;
  for (int k = 0; k < 4; ++k) c[k] = imageToTable(d.corners[k]);
  const cv::Point2d centre = imageToTable(d.center());
  // The marker's +x: mean of its top edge (0->1) and bottom edge (3->2) in the table.
  const cv::Point2d ex = (c[1] - c[0]) + (c[2] - c[3]);
  // The marker's +x rotated by +90 deg, from the left/right edges (3->0, 2->1), averaged in.
  const cv::Point2d ey = (c[0] - c[3]) + (c[1] - c[2]);
  // Image y points down but table y up, so printed "up" (3->0) is the marker's +y.
  const double yaw = std::atan2(ex.y - ey.x, ex.x + ey.y);
  PlanarPose p{centre.x, centre.y, wrapAngle(yaw)};
  if (height_m != 0.0 && camera_center_) {
    // The ray through the marker hits the table plane further from the nadir than the
    // marker: scale the offset from the nadir back by (H - h) / H.
    const cv::Vec3d& C = *camera_center_;
    const double k = (C[2] - height_m) / C[2];
    p.x = C[0] + (p.x - C[0]) * k;
    p.y = C[1] + (p.y - C[1]) * k;
  }
  return p;
}

}  // namespace ddace::vision
