#include "ddace/vision/tracker.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <opencv2/imgproc.hpp>

#include "ddace/common/file.h"
#include "yaml_values.h"

namespace ddace::vision {

using detail::booleanOr;
using detail::integerOr;
using detail::numberOr;
using detail::parseRoot;
using detail::stringOr;

const EntityMarker* MarkerConfig::entityById(int id) const {
  for (const auto& e : entities)
    if (e.id == id) return &e;
  return nullptr;
}

bool MarkerConfig::isCorner(int id) const {
  for (const auto& c : corners)
    if (c.id == id) return true;
  return false;
}

MarkerConfig parseMarkerConfig(const std::string& text, const std::string& file) {
  YamlChecker r(file);
  MarkerConfig mc;
  const YAML::Node root = parseRoot(r, text, "markers.yaml");
  r.onlyKeys(root, {"backend", "family", "corners", "corner_size", "default_size", "default_height", "entities"},
             "markers.yaml");
  const std::string backend = stringOr(r, root, "backend", toString(mc.backend));
  const std::optional<DetectorBackend> known_backend = parseDetectorBackend(backend);
  if (known_backend) mc.backend = *known_backend;
  else r.error(root["backend"], "backend must be 'aruco' or 'apriltag' (got '" + backend + "')");
  mc.family = stringOr(r, root, "family", mc.backend == DetectorBackend::AprilTag ? "tag36h11" : "DICT_4X4_50");
  int family_size = 0;
  {
    DetectorConfig dc;
    dc.backend = mc.backend;
    dc.family = mc.family;
    try {
      family_size = familySize(dc);
    } catch (const Error& e) {
      if (known_backend) r.error(root["family"], e.what());
    }
  }
  mc.corner_size_m = numberOr(r, root, "corner_size", mc.corner_size_m, 1e-3, 1.0);
  const double default_size = numberOr(r, root, "default_size", 0.03, 1e-3, 1.0);
  const double default_height = numberOr(r, root, "default_height", 0.0, 0.0, 1.0);

  std::set<int> ids;
  auto checkId = [&](const YAML::Node& node, int id) {
    if (family_size > 0 && (id < 0 || id >= family_size))
      r.error(node, "marker id " + std::to_string(id) + " is outside " + mc.family + " (ids 0.." +
                        std::to_string(family_size - 1) + ")");
    if (!ids.insert(id).second) r.error(node, "marker id " + std::to_string(id) + " is used twice");
  };

  const YAML::Node corners = root["corners"];
  if (corners.IsDefined() && !corners.IsNull()) {
    if (!corners.IsSequence()) {
      r.error(corners, "'corners' must be a list of {id, x, y}");
    } else {
      for (const auto& c : corners) {
        if (!r.expectMap(c, "a corner")) continue;
        r.onlyKeys(c, {"id", "x", "y"}, "a corner");
        if (!c["id"] || !c["x"] || !c["y"]) {
          r.error(c, "a corner needs id, x and y (metres, table frame)");
          continue;
        }
        CornerMarker cm;
        cm.id = integerOr(r, c, "id", -1);
        cm.table_xy = {numberOr(r, c, "x", 0), numberOr(r, c, "y", 0)};
        checkId(c["id"], cm.id);
        mc.corners.push_back(cm);
      }
      if (mc.corners.size() != 4)
        r.error(corners, "'corners' needs exactly four markers (got " + std::to_string(mc.corners.size()) +
                             "); leave it out to use a calibrated camera instead");
    }
  }

  const YAML::Node entities = root["entities"];
  std::set<std::string> names;
  if (!entities.IsDefined() || !entities.IsSequence() || entities.size() == 0) {
    r.error(entities.IsDefined() ? entities : root, "'entities' must be a non-empty list of {id, name, kind}");
  } else {
    for (const auto& e : entities) {
      if (!r.expectMap(e, "an entity")) continue;
      r.onlyKeys(e, {"id", "name", "kind", "type", "size", "height", "yaw_offset"}, "an entity");
      if (!e["id"] || !e["name"]) {
        r.error(e, "an entity needs at least id and name");
        continue;
      }
      EntityMarker em;
      em.id = integerOr(r, e, "id", -1);
      checkId(e["id"], em.id);
      em.name = stringOr(r, e, "name", "");
      if (!task::isValidName(em.name))
        r.error(e["name"], "entity name '" + em.name + "' must match [A-Za-z][A-Za-z0-9_]*");
      else if (!names.insert(em.name).second) r.error(e["name"], "entity name '" + em.name + "' is used twice");
      const std::string kind = stringOr(r, e, "kind", "robot");
      const auto k = task::entityKindFromString(kind);
      if (!k) r.error(e["kind"], "kind must be robot, object or goal (got '" + kind + "')");
      else em.kind = *k;
      em.type = stringOr(r, e, "type", "");
      em.size_m = numberOr(r, e, "size", default_size, 1e-3, 1.0);
      em.height_m = numberOr(r, e, "height", default_height, 0.0, 1.0);
      em.yaw_offset_rad = numberOr(r, e, "yaw_offset", 0.0, -2 * M_PI, 2 * M_PI);
      mc.entities.push_back(em);
    }
  }
  r.throwIfErrors();
  return mc;
}

MarkerConfig loadMarkerConfig(const std::string& path) {
  return parseMarkerConfig(readTextFile(path), path);
}

void requireTaskEntities(const MarkerConfig& markers, const std::string& markers_file, const task::TaskSpec& task,
                         const std::string& task_file) {
  std::string missing, other_kind;
  for (const auto& e : task.entities) {
    const auto m = std::find_if(markers.entities.begin(), markers.entities.end(),
                                [&](const EntityMarker& marker) { return marker.name == e.name; });
    if (m == markers.entities.end())
      missing += (missing.empty() ? "" : ", ") + e.name + " (" + task::toString(e.kind) + ")";
    else if (m->kind != e.kind)
      other_kind += (other_kind.empty() ? "" : ", ") + e.name + " is of kind " + task::toString(m->kind) + " there, " +
                    task::toString(e.kind) + " in the task";
  }
  if (missing.empty() && other_kind.empty()) return;
  std::string what = markers_file + " does not fit task '" + task.name + "' (" + task_file + "): ";
  if (!missing.empty()) what += "no marker for " + missing + (other_kind.empty() ? "" : "; ");
  what += other_kind;
  throw Error(what +
              ". The tracker would never report them and the run would wait for them: give the task's own markers "
              "file (markers:=FILE; `ddace init` writes one for exactly the task's entities) or add them to this one");
}

void parseTrackerTuning(const std::string& text, const std::string& file, TrackerConfig& config) {
  YamlChecker r(file);
  const YAML::Node root = parseRoot(r, text, "tracker.yaml");
  r.onlyKeys(root, {"aruco", "apriltag", "roi", "filter", "table"}, "tracker.yaml");
  if (const YAML::Node n = root["table"]; n.IsDefined() && r.expectMap(n, "'table'")) {
    r.onlyKeys(n, {"max_reprojection_px", "smoothing"}, "'table'");
    config.table.max_reprojection_px =
        numberOr(r, n, "max_reprojection_px", config.table.max_reprojection_px, 0.01, 1000.0);
    config.table.smoothing = numberOr(r, n, "smoothing", config.table.smoothing, 0.01, 1.0);
  }
  DetectorConfig& d = config.detector;
  if (const YAML::Node a = root["aruco"]; a.IsDefined() && r.expectMap(a, "'aruco'")) {
    r.onlyKeys(a, {"subpixel", "subpixel_window", "window_min", "window_max", "window_step", "sized_window"},
               "'aruco'");
    d.aruco_sized_window = numberOr(r, a, "sized_window", d.aruco_sized_window, 0.0, 10.0);
    d.aruco_subpixel = booleanOr(r, a, "subpixel", d.aruco_subpixel);
    d.aruco_subpixel_window = integerOr(r, a, "subpixel_window", d.aruco_subpixel_window, 1, 50);
    d.aruco_window_min = integerOr(r, a, "window_min", d.aruco_window_min, 3, 999);
    d.aruco_window_max = integerOr(r, a, "window_max", d.aruco_window_max, 3, 999);
    d.aruco_window_step = integerOr(r, a, "window_step", d.aruco_window_step, 1, 999);
    if (d.aruco_window_max < d.aruco_window_min) r.error(a, "aruco window_max must be >= window_min");
  }
  if (const YAML::Node a = root["apriltag"]; a.IsDefined() && r.expectMap(a, "'apriltag'")) {
    r.onlyKeys(a, {"engine", "decimate", "sigma", "max_hamming"}, "'apriltag'");
    const std::string engine = stringOr(r, a, "engine", toString(d.apriltag_engine));
    if (const auto e = parseAprilTagEngine(engine)) d.apriltag_engine = *e;
    else r.error(a["engine"], "apriltag engine must be 'opencv' or 'libapriltag' (got '" + engine + "')");
    d.apriltag_decimate = numberOr(r, a, "decimate", d.apriltag_decimate, 1.0, 8.0);
    d.apriltag_sigma = numberOr(r, a, "sigma", d.apriltag_sigma, 0.0, 5.0);
    d.apriltag_max_hamming = integerOr(r, a, "max_hamming", d.apriltag_max_hamming, 0, 2);
  }
  if (const YAML::Node n = root["roi"]; n.IsDefined() && r.expectMap(n, "'roi'")) {
    if (n["lost_growth"])
      r.error(n["lost_growth"], "'roi.lost_growth' is gone: regions now grow at filter.max_speed (one speed for both)");
    r.onlyKeys(n, {"enabled", "full_frame_every", "margin", "min_margin_px", "track_corners", "lost_growth"}, "'roi'");
    config.roi.track_corners = booleanOr(r, n, "track_corners", config.roi.track_corners);
    config.roi.enabled = booleanOr(r, n, "enabled", config.roi.enabled);
    config.roi.full_frame_every = integerOr(r, n, "full_frame_every", config.roi.full_frame_every, 1, 100000);
    config.roi.margin = numberOr(r, n, "margin", config.roi.margin, 0.0, 20.0);
    config.roi.min_margin_px = integerOr(r, n, "min_margin_px", config.roi.min_margin_px, 0, 10000);
  }
  if (const YAML::Node n = root["filter"]; n.IsDefined() && r.expectMap(n, "'filter'")) {
    r.onlyKeys(n,
               {"max_speed", "max_yaw_rate", "gate_margin", "reacquire_after", "hold", "max_drift", "position_gain",
                "yaw_gain"},
               "'filter'");
    FilterConfig& f = config.filter;
    f.max_speed_mps = numberOr(r, n, "max_speed", f.max_speed_mps, 1e-3, 100.0);
    f.max_yaw_rate_rps = numberOr(r, n, "max_yaw_rate", f.max_yaw_rate_rps, 1e-3, 1000.0);
    f.gate_margin_m = numberOr(r, n, "gate_margin", f.gate_margin_m, 0.0, 10.0);
    f.reacquire_after = integerOr(r, n, "reacquire_after", f.reacquire_after, 1, 1000);
    f.hold_s = numberOr(r, n, "hold", f.hold_s, 0.0, 60.0);
    f.max_drift_m = numberOr(r, n, "max_drift", f.max_drift_m, 0.0, 100.0);
    f.position_gain = numberOr(r, n, "position_gain", f.position_gain, 0.01, 1.0);
    f.yaw_gain = numberOr(r, n, "yaw_gain", f.yaw_gain, 0.01, 1.0);
  }
  r.throwIfErrors();
}

TrackerConfig loadTrackerConfig(const std::string& markers_path, const std::string& tracker_path) {
  TrackerConfig c;
  c.markers = loadMarkerConfig(markers_path);
  c.detector.backend = c.markers.backend;
  c.detector.family = c.markers.family;
  if (!tracker_path.empty()) parseTrackerTuning(readTextFile(tracker_path), tracker_path, c);
  return c;
}

std::string heightCorrectionName(HeightCorrection state) {
  switch (state) {
    case HeightCorrection::On:
      return "on";
    case HeightCorrection::NoIntrinsics:
      return "off: no intrinsics";
    case HeightCorrection::IntrinsicsDoNotFit:
      return "off: the intrinsics do not fit the table frame";
  }
  return "?";
}

std::vector<cv::Rect> mergeRegions(std::vector<cv::Rect> rects) {
  // Each rectangle with the area of the regions it stands for: a merge must not cost
  // more than half again what its parts needed, or a chain of neighbours would grow
  // into one region spanning the table.
  std::vector<double> needed;
  for (const auto& r : rects) needed.push_back(r.area());
  bool merged = true;
  while (merged) {
    merged = false;
    for (size_t i = 0; i < rects.size() && !merged; ++i)
      for (size_t j = i + 1; j < rects.size() && !merged; ++j)
        if ((rects[i] & rects[j]).area() > 0 && (rects[i] | rects[j]).area() <= 1.5 * (needed[i] + needed[j])) {
          rects[i] |= rects[j];
          needed[i] += needed[j];
          rects.erase(rects.begin() + static_cast<long>(j));
          needed.erase(needed.begin() + static_cast<long>(j));
          merged = true;
        }
  }
  return rects;
}

Tracker::Tracker(TrackerConfig config) : config_(std::move(config)) {
  config_.detector.backend = config_.markers.backend;
  config_.detector.family = config_.markers.family;
  detector_ = makeDetector(config_.detector);
  // The second look at an AprilTag missed where it was expected: libapriltag at full
  // resolution, which reads the small cells (3 px) that OpenCV's bit sampling and a
  // decimated segmentation miss now and then. Aruco's second look is the wide region
  // with OpenCV's every threshold window.
  if (config_.detector.backend == DetectorBackend::AprilTag &&
      (config_.detector.apriltag_engine == AprilTagEngine::OpenCv || config_.detector.apriltag_decimate > 1.0)) {
    DetectorConfig fine = config_.detector;
    fine.apriltag_engine = AprilTagEngine::LibAprilTag;
    fine.apriltag_decimate = 1.0;
    second_look_ = makeDetector(fine);
  }
  filters_.assign(config_.markers.entities.size(), PoseFilter(config_.filter));
}

Tracker::~Tracker() = default;

void Tracker::setCamera(const CameraModel& camera) {
  camera_ = camera;
  if (table_ && camera_.valid && !fixed_table_) table_->setIntrinsics(camera_.K);
}

HeightCorrection Tracker::heightCorrection() const {
  if (!camera_.valid) return HeightCorrection::NoIntrinsics;
  if (table_ && !table_->cameraCenter()) return HeightCorrection::IntrinsicsDoNotFit;
  return HeightCorrection::On;
}

std::optional<ParallaxEstimate> Tracker::parallaxWithoutIntrinsics() const {
  if (camera_.valid || !table_) return std::nullopt;
  double height = 0;
  for (const auto& e : config_.markers.entities) height = std::max(height, e.height_m);
  std::vector<cv::Point2d> area;
  for (const auto& c : config_.markers.corners) area.push_back(c.table_xy);
  return estimateParallaxWithoutIntrinsics(*table_, image_size_, height, area);
}

void Tracker::setFixedTableFrame(const TableFrame& frame) {
  table_ = frame;
  fixed_table_ = true;
}

std::vector<Tracker::Region> Tracker::regions(const cv::Size& size, double stamp, Reach reach,
                                              const std::set<int>& ids) const {
  std::vector<cv::Rect> rects;
  std::vector<double> sides;
  const cv::Rect whole(0, 0, size.width, size.height);
  for (const int id : ids) {
    const auto seen = last_seen_px_.find(id);
    if (seen == last_seen_px_.end()) continue;
    const Detection& det = seen->second;
    const cv::Rect last = cv::boundingRect(std::vector<cv::Point2f>(det.corners.begin(), det.corners.end()));
    const double dt = std::max(0.0, stamp - last_seen_t_.at(id));
    const EntityMarker* em = config_.markers.entityById(id);
    const double px_per_m = det.sidePx() / (em ? em->size_m : config_.markers.corner_size_m);
    cv::Rect predicted = last;
    if (const auto v = velocity_px_.find(id); v != velocity_px_.end())
      predicted = cv::Rect(last.tl() + cv::Point(cvRound(v->second.x * dt), cvRound(v->second.y * dt)), last.size());
    // Context for the thresholding around the marker, plus how far it may be from where
    // it was expected: gate_margin from the prediction (what the filter always accepts),
    // or, for a second look, anywhere the filter would accept it since it was seen
    // (max_speed x dt), around its last position and the predicted one.
    double reach_m = config_.filter.gate_margin_m;
    cv::Rect box = predicted;
    if (reach == Reach::MaxSpeed) {
      reach_m += config_.filter.max_speed_mps * dt;
      box |= last;
    }
    const double margin =
        std::max<double>(config_.roi.min_margin_px, config_.roi.margin * det.sidePx()) + reach_m * px_per_m;
    const int m = static_cast<int>(std::ceil(margin));
    // Even origins keep a decimating detector (AprilTag) on the full frame's sampling grid.
    const int x0 = (box.x - m) & ~1, y0 = (box.y - m) & ~1;
    box = cv::Rect(x0, y0, box.x + box.width + m - x0, box.y + box.height + m - y0) & whole;
    if (box.empty()) continue;
    rects.push_back(box);
    sides.push_back(det.sidePx());
  }
  // A merged region expects the mean size of the markers it was merged from.
  std::vector<Region> out;
  for (const cv::Rect& merged : mergeRegions(rects)) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < rects.size(); ++i)
      if ((rects[i] & merged) == rects[i]) sum += sides[i], ++n;
    out.push_back({merged, n > 0 ? sum / n : 0.0});
  }
  return out;
}

std::set<int> Tracker::trackedIds(bool full_frame) const {
  std::set<int> ids;
  for (const auto& [id, det] : last_seen_px_)
    if (full_frame || config_.roi.track_corners || !table_ || !config_.markers.isCorner(id)) ids.insert(id);
  return ids;
}

std::set<int> Tracker::absentIds(const std::set<int>& found) const {
  // Every configured marker is expected on the table; corner markers only while they are
  // searched between full-frame passes at all.
  std::set<int> ids;
  for (const auto& e : config_.markers.entities) ids.insert(e.id);
  if (config_.roi.track_corners || !table_)
    for (const auto& c : config_.markers.corners) ids.insert(c.id);
  for (const auto& [id, det] : last_seen_px_) ids.erase(id);
  for (const int id : found) ids.erase(id);
  return ids;
}

double Tracker::expectedSidePx(int id) const {
  // Pixels per metre from the markers tracked now (a tilted camera changes it by some
  // 10 % across the table; the candidates allow for more).
  std::vector<double> px_per_m;
  for (const auto& [seen, det] : last_seen_px_) {
    const EntityMarker* em = config_.markers.entityById(seen);
    px_per_m.push_back(det.sidePx() / (em ? em->size_m : config_.markers.corner_size_m));
  }
  if (px_per_m.empty()) return 0;
  std::nth_element(px_per_m.begin(), px_per_m.begin() + static_cast<long>(px_per_m.size() / 2), px_per_m.end());
  const EntityMarker* em = config_.markers.entityById(id);
  return px_per_m[px_per_m.size() / 2] * (em ? em->size_m : config_.markers.corner_size_m);
}

std::vector<Tracker::Region> Tracker::quadCandidates(double side_min, double side_max,
                                                     const std::vector<cv::Rect>& covered) {
  // The black square of a marker, outlined as the detectors do (an adaptive threshold
  // with a window of half its edge, the contour's polygon), on an image reduced to about
  // kSidePx per marker edge: a quarter or less of the pixels of one thresholding pass of
  // the whole frame. Only the detector, run in a region around each candidate, decides.
  constexpr double kSidePx = 12;  // edge of the smallest expected marker in the reduced image
  const int k = std::max(1, static_cast<int>(side_min / kSidePx));
  if (k > 1) cv::resize(gray_, small_, cv::Size(gray_.cols / k, gray_.rows / k), 0, 0, cv::INTER_AREA);
  else small_ = gray_;
  const double lo = side_min / k, hi = side_max / k;
  const int window = std::max(3, 2 * static_cast<int>(std::lround(0.25 * lo)) + 1);
  cv::adaptiveThreshold(small_, binary_, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, window, 7);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(binary_, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  const cv::Rect whole(0, 0, gray_.cols, gray_.rows);
  std::vector<cv::Rect> rects;
  std::vector<double> sides;
  std::vector<cv::Point> quad;
  for (const auto& c : contours) {
    // Contour points of a square of edge s: 4 s, down to 2.8 s turned by 45 degrees.
    const double n = static_cast<double>(c.size());
    if (n < 0.5 * 4 * lo || n > 1.6 * 4 * hi) continue;
    cv::approxPolyDP(c, quad, 0.05 * n, true);
    if (quad.size() != 4 || !cv::isContourConvex(quad)) continue;
    const double side = cv::arcLength(quad, true) / 4 * k;
    if (side < 0.6 * side_min || side > 1.6 * side_max) continue;
    const cv::Rect b = cv::boundingRect(quad);
    const cv::Rect box(b.x * k, b.y * k, b.width * k, b.height * k);
    const cv::Point centre = (box.tl() + box.br()) / 2;
    if (std::any_of(covered.begin(), covered.end(), [&](const cv::Rect& r) { return r.contains(centre); })) continue;
    const int m =
        static_cast<int>(std::ceil(std::max<double>(config_.roi.min_margin_px, config_.roi.margin * side))) + k;
    const int x0 = (box.x - m) & ~1, y0 = (box.y - m) & ~1;
    const cv::Rect grown = cv::Rect(x0, y0, box.x + box.width + m - x0, box.y + box.height + m - y0) & whole;
    if (grown.empty()) continue;
    rects.push_back(grown);
    sides.push_back(side);
  }
  std::vector<Region> out;
  for (const cv::Rect& merged : mergeRegions(rects)) {
    double sum = 0;
    int count = 0;
    for (size_t i = 0; i < rects.size(); ++i)
      if ((rects[i] & merged) == rects[i]) sum += sides[i], ++count;
    out.push_back({merged, count > 0 ? sum / count : 0.0});
  }
  return out;
}

void Tracker::toGray(const cv::Mat& image) {
  if (image.empty()) throw Error("tracker: empty image");
  if (image.channels() == 3) cv::cvtColor(image, gray_, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4) cv::cvtColor(image, gray_, cv::COLOR_BGRA2GRAY);
  else if (image.type() == CV_8UC1) gray_ = image;
  else throw Error("tracker: unsupported image type (need 8-bit mono, BGR or BGRA)");
  if (camera_.valid && camera_.image_size.area() > 0 && gray_.size() != camera_.image_size)
    throw Error("tracker: the image is " + std::to_string(gray_.cols) + "x" + std::to_string(gray_.rows) +
                " but the camera calibration is for " + std::to_string(camera_.image_size.width) + "x" +
                std::to_string(camera_.image_size.height));
}

struct Tracker::FrameSearch {
  const cv::Mat& gray;
  FrameResult& result;
  std::vector<Detection> found;
  std::set<int> found_ids;

  /// Every detection of `detector` in `rois`, the first of each id kept. `sized`: tell
  /// the detector the size of the markers expected in each region.
  void search(FiducialDetector& detector, const std::vector<Region>& rois, bool sized) {
    for (const auto& roi : rois)
      for (const auto& d : detector.detect(gray, roi.rect, sized ? roi.side_px : 0.0))
        if (found_ids.insert(d.id).second) found.push_back(d);
  }
  /// Regions grown around missed or fast markers can cost more than the whole frame
  /// (merged regions cost about their area).
  bool tooLarge(const std::vector<Region>& rois) const {
    constexpr double kFullFrameAbove = 0.75;  // fraction of the image
    double area = 0;
    for (const auto& r : rois) area += r.rect.area();
    return area > kFullFrameAbove * static_cast<double>(gray.total());
  }
  void addRois(const std::vector<Region>& rois) {
    for (const auto& r : rois) result.rois.push_back(r.rect);
  }
  static std::vector<Region> whole() { return {{cv::Rect(), 0.0}}; }
};

FrameResult Tracker::process(const cv::Mat& image, double stamp) {
  toGray(image);
  image_size_ = gray_.size();
  FrameResult result;
  result.stamp = stamp;
  const bool need_table = !table_ && !config_.markers.corners.empty();
  result.full_frame =
      !config_.roi.enabled || need_table || last_seen_px_.empty() || frames_ % config_.roi.full_frame_every == 0;
  ++frames_;
  FrameSearch s{gray_, result, {}, {}};
  lookForAbsent(s, lookWhereExpected(s, stamp));
  keepConfigured(s.found, stamp, result);
  // Regions follow markers seen recently; those unseen for longer than the hold are
  // searched for as absent ones.
  for (auto it = last_seen_px_.begin(); it != last_seen_px_.end();)
    it = stamp - last_seen_t_.at(it->first) <= config_.filter.hold_s ? std::next(it) : last_seen_px_.erase(it);
  updateEntities(stamp, result);
  return result;
}

std::set<int> Tracker::lookWhereExpected(FrameSearch& s, double stamp) {
  FrameResult& result = s.result;
  const auto missing = [&] {
    std::set<int> ids = trackedIds(result.full_frame);
    for (const int id : s.found_ids) ids.erase(id);
    return ids;
  };
  // First look: where each tracked marker is predicted, for markers of its size.
  std::vector<Region> first;
  if (!result.full_frame) {
    first = regions(gray_.size(), stamp, Reach::Predicted, trackedIds(false));
    if (s.tooLarge(first)) result.full_frame = true;
  }
  if (result.full_frame) s.search(*detector_, FrameSearch::whole(), false);
  else s.search(*detector_, first, true), s.addRois(first);

  // A marker missing where it was expected is looked for again at once, in this frame:
  // everywhere the filter would accept it (it moved unexpectedly), with the detector's
  // full search (every threshold window), then there with the second-look detector
  // (what the first could not see: a decimated image), so it never waits for a
  // full-frame pass. Once those regions would cover most of the image (a marker missing
  // for a while: they grow at filter.max_speed), it is searched for as an absent one.
  std::set<int> unfollowed;
  if (const std::set<int> lost = missing(); !lost.empty() && !result.full_frame) {
    result.first_look_misses = static_cast<int>(lost.size());
    const std::vector<Region> wide = regions(gray_.size(), stamp, Reach::MaxSpeed, lost);
    if (s.tooLarge(wide)) {
      unfollowed = lost;
    } else {
      s.search(*detector_, wide, false);
      s.addRois(wide);
    }
  }
  if (const std::set<int> lost = missing(); !lost.empty() && second_look_) {
    const std::vector<Region> wide = regions(gray_.size(), stamp, Reach::MaxSpeed, lost);
    if (!s.tooLarge(wide)) {
      s.search(*second_look_, wide, false);
      result.second_look = true;
    }
  }
  return unfollowed;
}

// A configured marker the regions do not follow (never seen, gone for longer than the
// hold: carried away, put back, missed by the first full-frame pass; or missing for so
// long that its region would cover most of the image) does not wait for the next
// full-frame pass either: the rest of the image is searched for marker-sized
// quadrilaterals, and the detector reads each, at the marker's size.
void Tracker::lookForAbsent(FrameSearch& s, const std::set<int>& unfollowed) {
  FrameResult& result = s.result;
  std::set<int> absent = absentIds(s.found_ids);
  for (const int id : unfollowed)
    if (!s.found_ids.count(id)) absent.insert(id);
  if (absent.empty() || result.full_frame) return;
  result.absent = static_cast<int>(absent.size());
  double side_min = 0, side_max = 0;
  for (const int id : absent) {
    const double side = expectedSidePx(id);
    side_min = side_min > 0 ? std::min(side_min, side) : side;
    side_max = std::max(side_max, side);
  }
  // Quadrilaterals that are markers found in this frame are known; any other is read,
  // even inside a region (a first look searched it for its own marker's size only).
  std::vector<cv::Rect> covered;
  for (const Detection& d : s.found)
    covered.push_back(cv::boundingRect(std::vector<cv::Point2f>(d.corners.begin(), d.corners.end())));
  const std::vector<Region> candidates = quadCandidates(side_min, side_max, covered);
  result.absent_candidates = static_cast<int>(candidates.size());
  if (s.tooLarge(candidates)) {
    // A full-frame pass as any other (every threshold window): the absent markers' sizes
    // may differ (corners and entities), and the frame is reported as searched whole.
    s.search(*detector_, FrameSearch::whole(), false);
    result.full_frame = true;
    result.rois.clear();
    return;
  }
  // Every threshold window in these small regions, then the second-look detector there
  // for what is still missing (as for a marker missed where it was expected).
  s.search(*detector_, candidates, false);
  s.addRois(candidates);
  const bool still_missing = std::any_of(absent.begin(), absent.end(), [&](int id) { return !s.found_ids.count(id); });
  if (still_missing && second_look_) {
    s.search(*second_look_, candidates, false);
    result.second_look = true;
  }
}

void Tracker::keepConfigured(const std::vector<Detection>& found, double stamp, FrameResult& result) {
  // An id seen twice (a reflection, a second print) is ambiguous: keep the one nearest its
  // last position.
  std::map<int, Detection> by_id;
  for (const auto& d : found) {
    if (!config_.markers.isCorner(d.id) && !config_.markers.entityById(d.id)) continue;
    auto it = by_id.find(d.id);
    if (it == by_id.end()) {
      by_id[d.id] = d;
      continue;
    }
    const auto last = last_seen_px_.find(d.id);
    if (last != last_seen_px_.end() &&
        cv::norm(d.center() - last->second.center()) < cv::norm(it->second.center() - last->second.center()))
      it->second = d;
  }
  for (const auto& [id, d] : by_id) {
    result.detections.push_back(d);
    const auto last = last_seen_px_.find(id);
    const double dt = last == last_seen_px_.end() ? 0.0 : stamp - last_seen_t_.at(id);
    if (dt > 0 && dt <= 0.25) {
      const cv::Point2f moved = d.center() - last->second.center();
      velocity_px_[id] = cv::Point2d(moved.x / dt, moved.y / dt);
    } else {
      velocity_px_.erase(id);  // first sighting, or after a gap: no velocity to trust
    }
    last_seen_px_[id] = d;
    last_seen_t_[id] = stamp;
  }
}

void Tracker::updateEntities(double stamp, FrameResult& result) {
  std::vector<Detection> undistorted;
  for (const auto& d : result.detections) {
    Detection u = d;
    const auto pts = camera_.undistort(std::vector<cv::Point2f>(d.corners.begin(), d.corners.end()));
    for (int k = 0; k < 4; ++k) u.corners[k] = pts[k];
    undistorted.push_back(u);
  }
  if (!fixed_table_ && !config_.markers.corners.empty()) updateTable(undistorted, result);
  result.table_valid = table_.has_value();
  result.height_correction = heightCorrection();
  if (table_) {
    for (const auto& u : undistorted) {
      for (size_t i = 0; i < config_.markers.entities.size(); ++i) {
        const EntityMarker& em = config_.markers.entities[i];
        if (em.id != u.id) continue;
        PlanarPose p = table_->markerPose(u, em.height_m);
        p.yaw = wrapAngle(p.yaw + em.yaw_offset_rad);
        filters_[i].update(p, stamp);
      }
    }
  }
  result.entities = states(stamp);
}

void Tracker::updateTable(const std::vector<Detection>& undistorted, FrameResult& result) {
  std::vector<Detection> corners;
  for (const auto& d : undistorted)
    if (config_.markers.isCorner(d.id)) corners.push_back(d);
  if (corners.size() != config_.markers.corners.size()) return;  // one is covered: keep the frame
  // The corner markers lie still: average their image positions over frames, unless
  // one jumped (the camera was moved), which starts the average again.
  bool jumped = corner_average_.size() != corners.size();
  for (const auto& d : corners) {
    const auto it = corner_average_.find(d.id);
    jumped = jumped || it == corner_average_.end();
    for (int k = 0; k < 4 && !jumped; ++k)
      jumped = cv::norm(d.corners[k] - it->second.corners[k]) > config_.table.max_reprojection_px;
  }
  const float g = jumped ? 1.0f : static_cast<float>(config_.table.smoothing);
  for (const auto& d : corners) {
    Detection& avg = corner_average_[d.id];
    if (jumped) avg = d;
    for (int k = 0; k < 4; ++k) avg.corners[k] += g * (d.corners[k] - avg.corners[k]);
  }
  std::vector<Detection> smoothed;
  for (const auto& [id, d] : corner_average_) smoothed.push_back(d);
  const TableFit fit = TableFrame::fitCornerMarkers(smoothed, config_.markers.corners, config_.markers.corner_size_m);
  if (!fit.frame) return;
  result.table_reprojection_px = fit.reprojection_px;
  if (fit.reprojection_px > config_.table.max_reprojection_px) {
    result.table_refused = true;
    return;
  }
  table_ = *fit.frame;
  if (camera_.valid) table_->setIntrinsics(camera_.K);  // heightCorrection() reports a misfit
  result.table_updated = true;
}

std::vector<EntityState> Tracker::states(double stamp) const {
  std::vector<EntityState> out;
  for (size_t i = 0; i < config_.markers.entities.size(); ++i) {
    const auto& em = config_.markers.entities[i];
    const PoseFilter& f = filters_[i];
    EntityState s;
    s.name = em.name;
    s.kind = em.kind;
    s.pose = f.pose();
    s.visible = f.visibleAt(stamp);
    // A goal is a print fixed to the table: hidden (robots parked on it), it is where it
    // was last seen, however long -- a run ending on it must not wait for it to reappear.
    s.stale = f.staleAt(stamp) && !(em.kind == task::EntityKind::Goal && f.everSeen());
    s.last_seen = f.everSeen() ? f.lastSeen() : 0.0;
    s.drift_m = f.driftAt(stamp);
    out.push_back(s);
  }
  return out;
}

}  // namespace ddace::vision
