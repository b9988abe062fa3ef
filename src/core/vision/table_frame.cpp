#include "ddace/vision/table_frame.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "ddace/common/error.h"

namespace ddace::vision {

double wrapAngle(double a) {
  a = std::fmod(a + M_PI, 2 * M_PI);
  if (a <= 0) a += 2 * M_PI;
  return a - M_PI;
}

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
  if (std::abs(n1 - n2) / std::max(n1, n2) > 0.2) return false;  // K does not fit this homography
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

cv::Point2d TableFrame::imageToTable(const cv::Point2d& px) const { return apply(H_, px); }
cv::Point2d TableFrame::tableToImage(const cv::Point2d& xy) const { return apply(Hinv_, xy); }

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
