// The tracker's debug image (tracker_node's ~debug_image): what was searched, what
// was found, what the tracker thinks.
//
// Owns: drawing one FrameResult over its camera frame. Must not: decide anything.
// Colours (BGR): detections green, corner markers magenta, a red dot at each marker's
// printed top-left corner, search regions blue; a status line (search mode, table
// frame and its reprojection error, height correction, stale entities).
#pragma once

#include <opencv2/core.hpp>

#include "ddace/vision/tracker.h"

namespace ddace::vision {

/// A BGR copy of `image` (grey or BGR) with `result` drawn over it.
cv::Mat drawDebugImage(const cv::Mat& image, const FrameResult& result, const MarkerConfig& markers);

}  // namespace ddace::vision
