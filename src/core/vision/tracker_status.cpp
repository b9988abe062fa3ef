#include <cmath>
#include <cstdio>

#include "ddace/vision/tracker.h"

namespace ddace::vision {

std::string tableRefusedText(const FrameResult& result, double max_reprojection_px) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "table frame refused: reprojection error %.2f px > table.max_reprojection_px %.2f (check the "
                "corner positions and corner_size in the markers file)",
                result.table_reprojection_px, max_reprojection_px);
  return buf;
}

TrackerStatus trackerStatus(const std::optional<FrameResult>& last, const std::optional<ParallaxEstimate>& parallax,
                            double max_reprojection_px) {
  TrackerStatus s;
  if (!last) {
    s.summary = "no frame yet";
    return s;
  }
  const FrameResult& fr = *last;
  for (const auto& e : fr.entities) {
    s.stale += e.stale;
    s.visible += e.visible;
  }
  using Level = TrackerStatus::Level;
  if (!fr.table_valid) {
    s.level = Level::Error;
    s.summary = fr.table_refused ? tableRefusedText(fr, max_reprojection_px)
                                 : "no table frame: not all four corner markers are visible";
  } else if (fr.height_correction != HeightCorrection::On) {
    s.level = Level::Warn;
    s.summary = "height correction " + heightCorrectionName(fr.height_correction);
    if (parallax) s.summary += " (up to " + std::to_string(std::lround(parallax->max_error_m * 1000)) + " mm)";
  } else if (fr.table_refused) {
    s.level = Level::Warn;
    s.summary = tableRefusedText(fr, max_reprojection_px);
  } else {
    s.level = Level::Ok;
    s.summary = "tracking";
  }
  return s;
}

}  // namespace ddace::vision
