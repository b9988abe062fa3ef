// Detection on rendered markers: both backends find every id with sub-pixel corners
// in the documented order.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "ddace/common/error.h"
#include "ddace/vision/detector.h"

using namespace ddace::vision;

namespace {

/// Pastes marker `id` with a cell size of `cell_px` at (x0, y0) (top-left of the
/// quiet zone) and returns the expected corners of its black square.
std::array<cv::Point2f, 4> paste(cv::Mat& img, const DetectorConfig& cfg, int id, int x0, int y0, int cell_px) {
  const MarkerImage m = renderMarker(cfg, id);
  cv::Mat big;
  cv::resize(m.cells, big, cv::Size(), cell_px, cell_px, cv::INTER_NEAREST);
  big.copyTo(img(cv::Rect(x0, y0, big.cols, big.rows)));
  // Pixel centres at integers: the square's edge lies half a pixel before its first pixel.
  const float a = x0 + m.square_offset * cell_px - 0.5f, b = y0 + m.square_offset * cell_px - 0.5f;
  const float s = static_cast<float>(m.square_cells * cell_px);
  return {cv::Point2f(a, b), cv::Point2f(a + s, b), cv::Point2f(a + s, b + s), cv::Point2f(a, b + s)};
}

void expectFindsAll(const DetectorConfig& cfg) {
  cv::Mat img(480, 640, CV_8UC1, cv::Scalar(230));
  std::map<int, std::array<cv::Point2f, 4>> expected;
  for (int i = 0; i < 6; ++i)
    expected[i * 3 + 1] = paste(img, cfg, i * 3 + 1, 30 + (i % 3) * 200, 40 + (i / 3) * 220, 12);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 0.8);
  auto det = makeDetector(cfg);
  const auto found = det->detect(img);
  ASSERT_EQ(found.size(), expected.size()) << det->name();
  for (const auto& d : found) {
    ASSERT_TRUE(expected.count(d.id)) << "unexpected id " << d.id;
    for (int k = 0; k < 4; ++k)
      EXPECT_LT(cv::norm(d.corners[k] - expected[d.id][k]), 0.6) << det->name() << " id " << d.id << " corner " << k;
  }
}

}  // namespace

TEST(Detector, ArucoFindsEveryMarkerWithCornersInPrintedOrder) {
  DetectorConfig cfg;
  cfg.backend = DetectorBackend::Aruco;
  cfg.family = "DICT_4X4_50";
  expectFindsAll(cfg);
}

TEST(Detector, ArucoAprilTagDictionaryUsesTheAprilTagPrintOrientation) {
  DetectorConfig cfg;
  cfg.backend = DetectorBackend::Aruco;
  cfg.family = "DICT_APRILTAG_36h11";
  expectFindsAll(cfg);
}

TEST(Detector, AprilTagFindsEveryMarkerWithCornersInPrintedOrder) {
  DetectorConfig cfg;
  cfg.backend = DetectorBackend::AprilTag;
  cfg.family = "tag36h11";
  for (const AprilTagEngine engine : {AprilTagEngine::LibAprilTag, AprilTagEngine::OpenCv}) {
    cfg.apriltag_engine = engine;
    expectFindsAll(cfg);
  }
}

TEST(Detector, AprilTagStandard41h12HasItsBorderInside) {
  DetectorConfig cfg;
  cfg.backend = DetectorBackend::AprilTag;
  cfg.family = "tagStandard41h12";
  cfg.apriltag_engine = AprilTagEngine::LibAprilTag;
  expectFindsAll(cfg);
  // OpenCV has no dictionary for it: a clear error, not another family.
  cfg.apriltag_engine = AprilTagEngine::OpenCv;
  try {
    makeDetector(cfg);
    FAIL() << "no error";
  } catch (const ddace::Error& e) {
    EXPECT_NE(std::string(e.what()).find("engine 'libapriltag'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(parseAprilTagEngine("opencv"), AprilTagEngine::OpenCv);
  EXPECT_EQ(toString(*parseAprilTagEngine("libapriltag")), "libapriltag");
  EXPECT_FALSE(parseAprilTagEngine("OpenCV").has_value());
}

TEST(Detector, ArucoSearchesForTheExpectedMarkerSize) {
  // A 30 px marker in a region: found with its size given (one threshold window), and
  // not when the region is said to hold markers four times larger.
  DetectorConfig cfg;
  auto det = makeDetector(cfg);
  cv::Mat img(300, 400, CV_8UC1, cv::Scalar(230));
  const auto expected = paste(img, cfg, 5, 200, 120, 5);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 0.8);
  const cv::Rect region(170, 90, 100, 100);
  const auto found = det->detect(img, region, 30.0);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].id, 5);
  for (int k = 0; k < 4; ++k) EXPECT_LT(cv::norm(found[0].corners[k] - expected[k]), 0.6) << "corner " << k;
  EXPECT_TRUE(det->detect(img, region, 120.0).empty());
  EXPECT_EQ(det->detect(img, region).size(), 1u);  // size unknown: the full search
}

TEST(Detector, BothBackendsAgreeOnTheSameAprilTagPrint) {
  // OpenCV's DICT_APRILTAG_36h11 and AprilTag's tag36h11 are the same markers: the
  // corners must coincide, so swapping backends does not move any pose.
  DetectorConfig a;
  a.backend = DetectorBackend::AprilTag;
  a.family = "tag36h11";
  DetectorConfig o;
  o.backend = DetectorBackend::Aruco;
  o.family = "DICT_APRILTAG_36h11";
  cv::Mat img(200, 200, CV_8UC1, cv::Scalar(230));
  paste(img, a, 7, 40, 50, 10);
  cv::Mat rotated;
  cv::warpAffine(img, rotated, cv::getRotationMatrix2D({100, 100}, 33, 1.0), img.size(), cv::INTER_LINEAR,
                 cv::BORDER_CONSTANT, cv::Scalar(230));
  const auto da = makeDetector(a)->detect(rotated);
  const auto dox = makeDetector(o)->detect(rotated);
  ASSERT_EQ(da.size(), 1u);
  ASSERT_EQ(dox.size(), 1u);
  EXPECT_EQ(da[0].id, 7);
  EXPECT_EQ(dox[0].id, 7);
  for (int k = 0; k < 4; ++k) EXPECT_LT(cv::norm(da[0].corners[k] - dox[0].corners[k]), 0.5) << "corner " << k;
}

TEST(Detector, RegionOfInterestReturnsFullImageCoordinates) {
  DetectorConfig cfg;
  auto det = makeDetector(cfg);
  cv::Mat img(300, 400, CV_8UC1, cv::Scalar(230));
  const auto expected = paste(img, cfg, 3, 250, 150, 8);
  const auto found = det->detect(img, cv::Rect(230, 130, 100, 100));
  ASSERT_EQ(found.size(), 1u);
  EXPECT_LT(cv::norm(found[0].corners[0] - expected[0]), 0.6);
  // A region that misses the marker finds nothing.
  EXPECT_TRUE(det->detect(img, cv::Rect(0, 0, 200, 140)).empty());
}

TEST(Detector, UnknownFamilyAndBackendNameTheKnownOnes) {
  DetectorConfig cfg;
  cfg.family = "DICT_9X9_1";
  try {
    makeDetector(cfg);
    FAIL() << "no error";
  } catch (const ddace::Error& e) {
    EXPECT_NE(std::string(e.what()).find("DICT_4X4_50"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(parseDetectorBackend("qr").has_value());
  EXPECT_EQ(parseDetectorBackend("apriltag"), DetectorBackend::AprilTag);
  EXPECT_EQ(toString(*parseDetectorBackend("aruco")), "aruco");
  cfg.backend = DetectorBackend::AprilTag;
  cfg.family = "tag36h11";
  EXPECT_THROW(renderMarker(cfg, 587), ddace::Error);  // tag36h11 has 587 ids: 0..586
  EXPECT_NO_THROW(renderMarker(cfg, 586));
}

TEST(Detector, RefusesColourImages) {
  auto det = makeDetector(DetectorConfig{});
  cv::Mat bgr(100, 100, CV_8UC3, cv::Scalar(200, 200, 200));
  EXPECT_THROW(det->detect(bgr), ddace::Error);
}
