// Fiducial detection behind one interface: OpenCV's aruco (contrib, 4.6 API) and
// AprilTag 3. Both return the four corners of every marker's outer black square in
// one order, so nothing downstream knows which backend ran.
//
// Owns: running a detector on a whole 8-bit grey image or on regions of it, and
// drawing markers (for printing and for the synthetic camera). Must not: know about
// the table, entities or time (table_frame.h, tracker.h do).
// Units: image pixels as in OpenCV: pixel centres at integer coordinates, x right, y down.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ddace::vision {

/// One detected marker. corners[] are the outer black square's corners in the
/// order of the printed marker: top-left, top-right, bottom-right, bottom-left
/// (as drawn by renderMarker, before any rotation), in full-image pixels.
struct Detection {
  int id = -1;
  std::array<cv::Point2f, 4> corners;
  /// Centre: intersection of the diagonals (perspective-correct, unlike the mean).
  cv::Point2f center() const;
  /// Mean edge length in pixels.
  double sidePx() const;
};

/// The fiducial detectors: OpenCV's ArUco module or AprilTag 3.
enum class DetectorBackend { Aruco, AprilTag };
/// "aruco", "apriltag": the names markers.yaml uses.
std::string toString(DetectorBackend backend);
/// The backend named `name` ("aruco", "apriltag"); nullopt for any other name.
std::optional<DetectorBackend> parseDetectorBackend(const std::string& name);

/// What reads AprilTag prints (backend apriltag): OpenCV's aruco module with its
/// DICT_APRILTAG_* dictionaries (tag16h5, tag25h9, tag36h10, tag36h11), or libapriltag
/// (every family). docs/vision.md gives the measurement behind the default.
enum class AprilTagEngine { OpenCv, LibAprilTag };
/// "opencv", "libapriltag": the names tracker.yaml uses.
std::string toString(AprilTagEngine engine);
std::optional<AprilTagEngine> parseAprilTagEngine(const std::string& name);
/// The engine that is not `engine`.
AprilTagEngine otherEngine(AprilTagEngine engine);

/// Which detector and which marker family. Loaded from tracker.yaml (tracker.h).
struct DetectorConfig {
  DetectorBackend backend = DetectorBackend::Aruco;
  std::string family = "DICT_4X4_50";  ///< aruco: DICT_4X4_50 ... DICT_APRILTAG_36h11;
                                       ///< apriltag: tag36h11, tag25h9, tag16h5, tagStandard41h12, ...
  // aruco
  bool aruco_subpixel = true;     ///< corner refinement CORNER_REFINE_SUBPIX
  int aruco_subpixel_window = 2;  ///< half-size of its window, pixels; keep it below the
                                  ///< white quiet zone or dark robot bodies pull corners out
  int aruco_window_min = 3;       ///< adaptive threshold windows, pixels: min, max, step
  int aruco_window_max = 23;      ///< (OpenCV's defaults; one window = one thresholding pass)
  int aruco_window_step = 10;
  double aruco_sized_window = 0.5;  ///< where the markers' size is known (a tracked marker's
                                    ///< region): ONE threshold window of this x the marker's
                                    ///< edge (odd, >= 3 px), perimeters within 0.6..1.6 x its
                                    ///< own; 0 = always the window range above
  // apriltag
  AprilTagEngine apriltag_engine = AprilTagEngine::OpenCv;  ///< tracker.yaml apriltag.engine
  double apriltag_decimate = 2.0;  ///< quad_decimate: segment a 1/d-size image (d = 1 is ~4x slower)
  double apriltag_sigma = 0.0;     ///< quad_sigma (Gaussian blur before segmentation), pixels
  int apriltag_max_hamming = 1;    ///< bits corrected when decoding (0..2)
};

/// Names accepted as DetectorConfig::family for `backend`.
std::vector<std::string> knownFamilies(DetectorBackend backend);

class FiducialDetector {
 public:
  virtual ~FiducialDetector() = default;
  /// Detects markers inside `roi` of the 8-bit single-channel `gray` (the whole
  /// image when roi is empty). Corners are returned in full-image pixels.
  /// A marker that is cut by the ROI border is not found. `expected_side_px`: the edge
  /// of the markers expected in the region (pixels), when known: the detector may then
  /// look for that size only (aruco: one threshold window matched to it, see
  /// DetectorConfig::aruco_sized_window); 0 = any size, the detector's full search.
  virtual std::vector<Detection> detect(const cv::Mat& gray, const cv::Rect& roi = cv::Rect(),
                                        double expected_side_px = 0) = 0;
  /// "aruco DICT_4X4_50", "apriltag tag36h11".
  virtual std::string name() const = 0;
};

/// Creates the configured detector. Throws ddace::Error naming the unknown family (and
/// listing the known ones).
std::unique_ptr<FiducialDetector> makeDetector(const DetectorConfig& config);

/// A printable marker, one pixel per cell, white quiet zone included.
struct MarkerImage {
  cv::Mat cells;          ///< CV_8UC1, 0 = black, 255 = white, square
  int square_offset = 0;  ///< cells from the image border to the detected square
  int square_cells = 0;   ///< edge of the detected (outer black) square in cells
};

/// Draws marker `id` of the configured family. Throws ddace::Error when the id is
/// out of the family's range.
MarkerImage renderMarker(const DetectorConfig& config, int id);

/// Number of ids in the configured family.
int familySize(const DetectorConfig& config);

}  // namespace ddace::vision
