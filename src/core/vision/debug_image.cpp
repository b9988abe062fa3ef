#include "ddace/vision/debug_image.h"

#include <cstdio>

#include <opencv2/imgproc.hpp>

namespace ddace::vision {

cv::Mat drawDebugImage(const cv::Mat& image, const FrameResult& fr, const MarkerConfig& markers) {
  cv::Mat out;
  if (image.channels() == 1) cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  else out = image.clone();
  for (const auto& r : fr.rois) cv::rectangle(out, r, cv::Scalar(255, 160, 0), 1);
  for (const auto& d : fr.detections) {
    std::vector<cv::Point> poly;
    for (const auto& c : d.corners) poly.emplace_back(cvRound(c.x), cvRound(c.y));
    const bool corner = markers.isCorner(d.id);
    cv::polylines(out, poly, true, corner ? cv::Scalar(255, 0, 255) : cv::Scalar(0, 220, 0), 2);
    cv::circle(out, poly[0], 3, cv::Scalar(0, 0, 255), cv::FILLED);  // printed top-left
    const EntityMarker* em = markers.entityById(d.id);
    const std::string label = em ? em->name : "corner " + std::to_string(d.id);
    cv::putText(out, label, poly[0] + cv::Point(0, -6), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 255), 1);
  }
  std::string status = fr.full_frame ? "full frame" : std::to_string(fr.rois.size()) + " regions";
  if (!fr.table_valid) status += ", NO TABLE FRAME";
  if (fr.table_reprojection_px >= 0) {
    char buf[64];
    std::snprintf(buf, sizeof buf, ", table %.2f px%s", fr.table_reprojection_px, fr.table_refused ? " REFUSED" : "");
    status += buf;
  }
  if (fr.height_correction != HeightCorrection::On)
    status += ", height correction " + heightCorrectionName(fr.height_correction);
  for (const auto& e : fr.entities)
    if (e.stale) status += ", " + e.name + " stale";
  cv::putText(out, status, cv::Point(10, 25), cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 255), 2);
  return out;
}

}  // namespace ddace::vision
