#include "ddace/vision/detector.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "ddace/common/error.h"

namespace ddace::vision {

cv::Point2f Detection::center() const {
  // Intersection of the diagonals 0-2 and 1-3: the projection of the square's centre.
  const cv::Point2f p = corners[0], r = corners[2] - corners[0];
  const cv::Point2f q = corners[1], s = corners[3] - corners[1];
  const float denom = r.x * s.y - r.y * s.x;
  if (std::abs(denom) < 1e-9f) return (corners[0] + corners[1] + corners[2] + corners[3]) * 0.25f;
  const float t = ((q.x - p.x) * s.y - (q.y - p.y) * s.x) / denom;
  return p + t * r;
}

double Detection::sidePx() const {
  double sum = 0;
  for (int i = 0; i < 4; ++i) sum += cv::norm(corners[(i + 1) % 4] - corners[i]);
  return sum / 4;
}

namespace {

const std::map<std::string, int>& arucoDictionaries() {
  using namespace cv::aruco;
  static const std::map<std::string, int> dicts = {
      {"DICT_4X4_50", DICT_4X4_50},
      {"DICT_4X4_100", DICT_4X4_100},
      {"DICT_4X4_250", DICT_4X4_250},
      {"DICT_4X4_1000", DICT_4X4_1000},
      {"DICT_5X5_50", DICT_5X5_50},
      {"DICT_5X5_100", DICT_5X5_100},
      {"DICT_5X5_250", DICT_5X5_250},
      {"DICT_5X5_1000", DICT_5X5_1000},
      {"DICT_6X6_50", DICT_6X6_50},
      {"DICT_6X6_100", DICT_6X6_100},
      {"DICT_6X6_250", DICT_6X6_250},
      {"DICT_6X6_1000", DICT_6X6_1000},
      {"DICT_7X7_50", DICT_7X7_50},
      {"DICT_7X7_100", DICT_7X7_100},
      {"DICT_7X7_250", DICT_7X7_250},
      {"DICT_7X7_1000", DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", DICT_ARUCO_ORIGINAL},
      {"DICT_APRILTAG_16h5", DICT_APRILTAG_16h5},
      {"DICT_APRILTAG_25h9", DICT_APRILTAG_25h9},
      {"DICT_APRILTAG_36h10", DICT_APRILTAG_36h10},
      {"DICT_APRILTAG_36h11", DICT_APRILTAG_36h11},
  };
  return dicts;
}

struct AprilFamily {
  std::function<apriltag_family_t*()> create;
  std::function<void(apriltag_family_t*)> destroy;
};

const std::map<std::string, AprilFamily>& aprilFamilies() {
  static const std::map<std::string, AprilFamily> families = {
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag36h10", {tag36h10_create, tag36h10_destroy}},
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
  };
  return families;
}

[[noreturn]] void unknownFamily(const DetectorConfig& config) {
  std::string list;
  for (const auto& f : knownFamilies(config.backend)) list += (list.empty() ? "" : ", ") + f;
  throw Error("unknown " + toString(config.backend) + " family '" + config.family + "' (known: " + list + ")");
}

cv::Rect clampRoi(const cv::Mat& gray, const cv::Rect& roi) {
  const cv::Rect whole(0, 0, gray.cols, gray.rows);
  return roi.empty() ? whole : (roi & whole);
}

void checkImage(const cv::Mat& gray) {
  if (gray.type() != CV_8UC1) throw Error("fiducial detection needs an 8-bit single-channel image");
}

class ArucoDetector : public FiducialDetector {
 public:
  /// `dictionary`: the aruco name of config.family (itself, or DICT_APRILTAG_36h11 for
  /// AprilTag's tag36h11 read by the OpenCV engine).
  ArucoDetector(const DetectorConfig& config, const std::string& dictionary) : config_(config) {
    const auto it = arucoDictionaries().find(dictionary);
    if (it == arucoDictionaries().end()) unknownFamily(config);
    dictionary_ = cv::aruco::getPredefinedDictionary(it->second);
    params_ = cv::aruco::DetectorParameters::create();
    apriltag_print_ = dictionary.rfind("DICT_APRILTAG", 0) == 0;
    if (config.aruco_subpixel) params_->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    if (config.aruco_subpixel_window < 1) throw Error("aruco subpixel_window must be >= 1");
    params_->cornerRefinementWinSize = config.aruco_subpixel_window;
    if (config.aruco_window_min < 3 || config.aruco_window_max < config.aruco_window_min ||
        config.aruco_window_step < 1)
      throw Error("aruco threshold windows: need 3 <= window_min <= window_max and window_step >= 1");
    params_->adaptiveThreshWinSizeMin = config.aruco_window_min;
    params_->adaptiveThreshWinSizeMax = config.aruco_window_max;
    params_->adaptiveThreshWinSizeStep = config.aruco_window_step;
    if (config.aruco_sized_window < 0) throw Error("aruco sized_window must be >= 0");
    roi_params_ = cv::aruco::DetectorParameters::create();
    *roi_params_ = *params_;
  }

  std::vector<Detection> detect(const cv::Mat& gray, const cv::Rect& roi_in, double expected_side_px) override {
    checkImage(gray);
    const cv::Rect roi = clampRoi(gray, roi_in);
    std::vector<Detection> out;
    if (roi.width < 8 || roi.height < 8) return out;
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    // The perimeter limits are relative to the searched image: keep the full image's
    // absolute limits in a region, or every speck of noise there becomes a candidate.
    const double roi_px = std::max(roi.width, roi.height);
    const double scale = static_cast<double>(std::max(gray.cols, gray.rows)) / roi_px;
    *roi_params_ = *params_;
    roi_params_->minMarkerPerimeterRate = std::min(4.0, params_->minMarkerPerimeterRate * scale);
    roi_params_->maxMarkerPerimeterRate =
        std::max(roi_params_->minMarkerPerimeterRate, params_->maxMarkerPerimeterRate * scale);
    const bool sized = expected_side_px > 0 && config_.aruco_sized_window > 0;
    if (sized) {
      // The markers' size is known: one thresholding pass with a window matched to it
      // instead of OpenCV's three, and only contours of about that perimeter.
      const int window =
          std::max(3, 2 * static_cast<int>(std::lround(config_.aruco_sized_window * expected_side_px / 2)) + 1);
      roi_params_->adaptiveThreshWinSizeMin = roi_params_->adaptiveThreshWinSizeMax = window;
      roi_params_->minMarkerPerimeterRate = 4 * 0.6 * expected_side_px / roi_px;
      roi_params_->maxMarkerPerimeterRate = 4 * 1.6 * expected_side_px / roi_px;
    }
    cv::aruco::detectMarkers(gray(roi), dictionary_, corners, ids, sized || scale > 1.0 ? roi_params_ : params_);
    const cv::Point2f offset(static_cast<float>(roi.x), static_cast<float>(roi.y));
    for (size_t i = 0; i < ids.size(); ++i) {
      Detection d;
      d.id = ids[i];
      // OpenCV's AprilTag dictionaries are the AprilTag prints turned by 180 degrees:
      // report corners in the print's order so both backends give the same yaw.
      const int turn = apriltag_print_ ? 2 : 0;
      for (int k = 0; k < 4; ++k) d.corners[k] = corners[i][(k + turn) % 4] + offset;
      out.push_back(d);
    }
    return out;
  }

  std::string name() const override {
    return config_.backend == DetectorBackend::Aruco ? "aruco " + config_.family
                                                     : "apriltag " + config_.family + " (opencv)";
  }

 private:
  DetectorConfig config_;
  cv::Ptr<cv::aruco::Dictionary> dictionary_;
  cv::Ptr<cv::aruco::DetectorParameters> params_, roi_params_;
  bool apriltag_print_ = false;
};

class AprilTagDetector : public FiducialDetector {
 public:
  explicit AprilTagDetector(const DetectorConfig& config) : config_(config) {
    const auto it = aprilFamilies().find(config.family);
    if (it == aprilFamilies().end()) unknownFamily(config);
    if (config.apriltag_max_hamming < 0 || config.apriltag_max_hamming > 2)
      throw Error("apriltag max_hamming must be 0, 1 or 2 (got " + std::to_string(config.apriltag_max_hamming) + ")");
    if (!(config.apriltag_decimate >= 1.0)) throw Error("apriltag decimate must be >= 1");
    destroy_family_ = it->second.destroy;
    family_ = it->second.create();
    detector_ = apriltag_detector_create();
    apriltag_detector_add_family_bits(detector_, family_, config.apriltag_max_hamming);
    detector_->quad_decimate = static_cast<float>(config.apriltag_decimate);
    detector_->quad_sigma = static_cast<float>(config.apriltag_sigma);
    detector_->nthreads = 1;
    detector_->refine_edges = true;
  }
  ~AprilTagDetector() override {
    apriltag_detector_destroy(detector_);
    destroy_family_(family_);
  }
  AprilTagDetector(const AprilTagDetector&) = delete;
  AprilTagDetector& operator=(const AprilTagDetector&) = delete;

  std::vector<Detection> detect(const cv::Mat& gray, const cv::Rect& roi_in, double /*expected_side_px*/) override {
    checkImage(gray);
    const cv::Rect roi = clampRoi(gray, roi_in);
    std::vector<Detection> out;
    if (roi.width < 8 || roi.height < 8) return out;
    // The detector may write into its input (blur); give it its own continuous copy.
    gray(roi).copyTo(buffer_);
    image_u8_t im{buffer_.cols, buffer_.rows, static_cast<int32_t>(buffer_.step[0]), buffer_.data};
    zarray_t* found = apriltag_detector_detect(detector_, &im);
    // AprilTag's corners wrap counter-clockwise from the tag's bottom-left, and it puts
    // pixel centres at +0.5 (OpenCV: at integers).
    static constexpr int kOrder[4] = {3, 2, 1, 0};
    const float ox = static_cast<float>(roi.x) - 0.5f, oy = static_cast<float>(roi.y) - 0.5f;
    for (int i = 0; i < zarray_size(found); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(found, i, &det);
      Detection d;
      d.id = det->id;
      for (int k = 0; k < 4; ++k)
        d.corners[k] =
            cv::Point2f(static_cast<float>(det->p[kOrder[k]][0]) + ox, static_cast<float>(det->p[kOrder[k]][1]) + oy);
      out.push_back(d);
    }
    apriltag_detections_destroy(found);
    return out;
  }

  std::string name() const override { return "apriltag " + config_.family + " (libapriltag)"; }

 private:
  DetectorConfig config_;
  apriltag_family_t* family_ = nullptr;
  std::function<void(apriltag_family_t*)> destroy_family_;
  apriltag_detector_t* detector_ = nullptr;
  cv::Mat buffer_;
};

}  // namespace

std::string toString(DetectorBackend backend) {
  return backend == DetectorBackend::AprilTag ? "apriltag" : "aruco";
}

std::optional<DetectorBackend> parseDetectorBackend(const std::string& name) {
  if (name == "aruco") return DetectorBackend::Aruco;
  if (name == "apriltag") return DetectorBackend::AprilTag;
  return std::nullopt;
}

std::vector<std::string> knownFamilies(DetectorBackend backend) {
  std::vector<std::string> names;
  if (backend == DetectorBackend::Aruco)
    for (const auto& kv : arucoDictionaries()) names.push_back(kv.first);
  else
    for (const auto& kv : aprilFamilies()) names.push_back(kv.first);
  return names;
}

std::string toString(AprilTagEngine engine) {
  return engine == AprilTagEngine::OpenCv ? "opencv" : "libapriltag";
}

std::optional<AprilTagEngine> parseAprilTagEngine(const std::string& name) {
  if (name == "opencv") return AprilTagEngine::OpenCv;
  if (name == "libapriltag") return AprilTagEngine::LibAprilTag;
  return std::nullopt;
}

AprilTagEngine otherEngine(AprilTagEngine engine) {
  return engine == AprilTagEngine::OpenCv ? AprilTagEngine::LibAprilTag : AprilTagEngine::OpenCv;
}

std::unique_ptr<FiducialDetector> makeDetector(const DetectorConfig& config) {
  if (config.backend == DetectorBackend::Aruco) return std::make_unique<ArucoDetector>(config, config.family);
  if (config.apriltag_engine == AprilTagEngine::LibAprilTag) return std::make_unique<AprilTagDetector>(config);
  // OpenCV's names of the AprilTag families it reads: "tag36h11" -> DICT_APRILTAG_36h11.
  if (aprilFamilies().count(config.family) && arucoDictionaries().count("DICT_APRILTAG_" + config.family.substr(3)))
    return std::make_unique<ArucoDetector>(config, "DICT_APRILTAG_" + config.family.substr(3));
  if (!aprilFamilies().count(config.family)) unknownFamily(config);
  throw Error("apriltag engine 'opencv' does not read " + config.family +
              " (it reads tag16h5, tag25h9, tag36h10 and tag36h11): use engine 'libapriltag'");
}

int familySize(const DetectorConfig& config) {
  if (config.backend == DetectorBackend::Aruco) {
    const auto it = arucoDictionaries().find(config.family);
    if (it == arucoDictionaries().end()) unknownFamily(config);
    return cv::aruco::getPredefinedDictionary(it->second)->bytesList.rows;
  }
  const auto it = aprilFamilies().find(config.family);
  if (it == aprilFamilies().end()) unknownFamily(config);
  apriltag_family_t* fam = it->second.create();
  const int n = static_cast<int>(fam->ncodes);
  it->second.destroy(fam);
  return n;
}

MarkerImage renderMarker(const DetectorConfig& config, int id) {
  const int n = familySize(config);
  if (id < 0 || id >= n)
    throw Error("marker id " + std::to_string(id) + " is outside " + toString(config.backend) + " " + config.family +
                " (ids 0.." + std::to_string(n - 1) + ")");
  MarkerImage m;
  if (config.backend == DetectorBackend::Aruco) {
    const auto dict = cv::aruco::getPredefinedDictionary(arucoDictionaries().at(config.family));
    const int cells = dict->markerSize + 2;  // data bits + one black border cell each side
    cv::Mat marker;
    cv::aruco::drawMarker(dict, id, cells, marker, 1);
    if (config.family.rfind("DICT_APRILTAG", 0) == 0) cv::rotate(marker, marker, cv::ROTATE_180);
    cv::copyMakeBorder(marker, m.cells, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(255));
    m.square_offset = 1;
    m.square_cells = cells;
    return m;
  }
  const auto& fam_fns = aprilFamilies().at(config.family);
  apriltag_family_t* fam = fam_fns.create();
  image_u8_t* im = apriltag_to_image(fam, id);
  cv::Mat view(im->height, im->width, CV_8UC1, im->buf, static_cast<size_t>(im->stride));
  cv::copyMakeBorder(view, m.cells, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(255));
  m.square_offset = (fam->total_width - fam->width_at_border) / 2 + 1;
  m.square_cells = fam->width_at_border;
  image_u8_destroy(im);
  fam_fns.destroy(fam);
  return m;
}

}  // namespace ddace::vision
