#include "ddace/vision/tracker_scenes.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/aruco.hpp>

namespace ddace::vision {

namespace {

constexpr int kFieldRobots = 12;
constexpr double kBallSpeed = 0.8;    // m/s
constexpr double kEdgeFalloff = 0.4;  // brightness lost toward the image's corners
constexpr double kNoiseSigma = 2.0;   // grey levels, as the synthetic camera's default

/// The edge scene's robots other than R1: centres of their small circles (metres),
/// on the lines of the corner markers, along all four edges of the table.
const std::vector<cv::Point2d>& edgeCentres() {
  static const std::vector<cv::Point2d> c = {{0.20, 0.03}, {0.40, 0.03}, {0.60, 0.03}, {0.20, 0.57}, {0.40, 0.57},
                                             {0.60, 0.57}, {0.77, 0.17}, {0.77, 0.30}, {0.77, 0.43}, {0.03, 0.30}};
  return c;
}

EntityMarker robot(int id, const std::string& name) {
  EntityMarker e;
  e.id = id;
  e.name = name;
  e.size_m = 0.03;
  e.height_m = 0.035;  // a Hamster's top
  return e;
}

}  // namespace

std::string toString(TrackerScene scene) {
  switch (scene) {
    case TrackerScene::Small:
      return "small";
    case TrackerScene::Fast:
      return "fast";
    case TrackerScene::Edge:
      return "edge";
  }
  return "?";
}

TrackerSceneRenderer::TrackerSceneRenderer(TrackerScene scene, DetectorBackend backend) : scene_(scene) {
  markers_.backend = backend;
  markers_.family = backend == DetectorBackend::Aruco ? "DICT_4X4_50" : "tag36h11";
  markers_.corner_size_m = 0.04;
  markers_.corners = {{0, {0.03, 0.03}}, {1, {0.77, 0.03}}, {2, {0.77, 0.57}}, {3, {0.03, 0.57}}};
  const int robots = scene == TrackerScene::Edge ? 1 + static_cast<int>(edgeCentres().size()) : kFieldRobots;
  for (int i = 0; i < robots; ++i) markers_.entities.push_back(robot(10 + i, "R" + std::to_string(i + 1)));
  if (scene == TrackerScene::Fast) {
    EntityMarker ball = robot(30, "ball");
    ball.kind = task::EntityKind::Object;
    ball.height_m = 0.04;
    markers_.entities.push_back(ball);
  }
  SyntheticCameraConfig c;
  c.width = 1280;
  c.height = 720;
  c.position = {0.4, -0.15, 1.0};  // about 9 degrees from straight down ...
  c.look_at = {0.4, 0.3};
  c.roll_deg = 3.0;  // ... and rolled
  c.light_gradient = 0.4;
  if (scene == TrackerScene::Edge) {
    // Vignetting instead of the gradient, and the noise after it (a sensor's noise does
    // not dim with the light).
    c.light_gradient = 0.0;
    c.noise_sigma = 0.0;
    noise_sigma_ = kNoiseSigma;
  }
  camera_ = std::make_unique<SyntheticCamera>(c, markers_);
  if (scene == TrackerScene::Edge) {
    // The falloff reaches kEdgeFalloff at the working area's corner furthest from the
    // image's centre (the table does not fill the image).
    const double cx = (c.width - 1) / 2.0, cy = (c.height - 1) / 2.0;
    double r2_edge = 0;
    for (const auto& [x, y] : {std::pair{0.0, 0.0}, {0.8, 0.0}, {0.8, 0.6}, {0.0, 0.6}}) {
      const cv::Point2d p = camera_->project({x, y, 0.0});
      r2_edge = std::max(r2_edge, (p.x - cx) * (p.x - cx) + (p.y - cy) * (p.y - cy));
    }
    falloff_ = cv::Mat(c.height, c.width, CV_32F);
    for (int r = 0; r < c.height; ++r)
      for (int col = 0; col < c.width; ++col)
        falloff_.at<float>(r, col) = static_cast<float>(
            std::max(0.3, 1.0 - kEdgeFalloff * ((col - cx) * (col - cx) + (r - cy) * (r - cy)) / r2_edge));
  }
}

std::vector<TrueEntity> TrackerSceneRenderer::truth(double t) const {
  std::vector<TrueEntity> out;
  if (scene_ == TrackerScene::Edge) {
    // R1: parked in the left near corner (beside corner marker 0) for a second, then out
    // to the middle at 0.1 m/s and back, again and again.
    const double s = std::fmod(std::max(0.0, t - 1.0), 6.0);
    const double d = 0.1 * (s < 3.0 ? s : 6.0 - s);
    out.push_back({"R1", {0.04 + 0.8 * d, 0.11 + 0.6 * d, std::atan2(0.6, 0.8)}});
    const auto& centres = edgeCentres();
    for (size_t i = 0; i < centres.size(); ++i) {
      const double a = (0.8 + 0.15 * static_cast<double>(i)) * t + static_cast<double>(i);
      out.push_back({"R" + std::to_string(i + 2),
                     {centres[i].x + 0.01 * std::cos(a), centres[i].y + 0.01 * std::sin(a), wrapAngle(a + M_PI / 2)}});
    }
    return out;
  }
  // Robots on small circles (up to 0.09 m/s) in two rows; the ball between them.
  for (int i = 0; i < kFieldRobots; ++i) {
    const double cx = 0.12 + 0.11 * (i % 6), cy = 0.13 + 0.34 * (i / 6);
    const double a = (1.0 + 0.2 * i) * t + i;
    out.push_back(
        {"R" + std::to_string(i + 1), {cx + 0.03 * std::cos(a), cy + 0.03 * std::sin(a), wrapAngle(a + M_PI / 2)}});
  }
  if (scene_ == TrackerScene::Fast) {
    const double s = std::fmod(kBallSpeed * t, 1.2);
    out.push_back({"ball", {s < 0.6 ? 0.1 + s : 0.7 - (s - 0.6), 0.30, 0.0}});
  }
  return out;
}

cv::Mat TrackerSceneRenderer::render(const std::vector<TrueEntity>& truth, double t_s) {
  cv::Mat img = camera_->render(truth, t_s);
  if (falloff_.empty()) return img;
  cv::Mat f, noise(img.size(), CV_32F);
  img.convertTo(f, CV_32F);
  f = f.mul(falloff_);
  rng_.fill(noise, cv::RNG::NORMAL, 0.0, noise_sigma_);
  f += noise;
  f.convertTo(img, CV_8U);
  return img;
}

std::vector<Detection> referenceDetect(const cv::Mat& gray, DetectorBackend backend) {
  // Made once, as a program that detects in every frame would (building
  // DICT_APRILTAG_36h11's 587 codes takes longer than a detection).
  static const auto params = cv::aruco::DetectorParameters::create();
  static const auto aruco = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  static const auto apriltag = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  const auto& dict = backend == DetectorBackend::Aruco ? aruco : apriltag;
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(gray, dict, corners, ids, params);
  std::vector<Detection> out(ids.size());
  for (size_t i = 0; i < ids.size(); ++i) {
    out[i].id = ids[i];
    for (int k = 0; k < 4; ++k) out[i].corners[k] = corners[i][k];
  }
  return out;
}

}  // namespace ddace::vision
