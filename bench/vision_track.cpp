// The overhead tracker against OpenCV's own full-frame aruco detector, in one run, on
// two 1280x720 scenes of the synthetic camera (tilted 9 degrees, rolled 3, 40 % light
// falloff, blur, noise): "small" = 4 corner markers + 12 robots with 3 cm markers on
// slow circles; "fast" = the same with a 3 cm ball passed across the table at
// 0.8 m/s. Both backends (for AprilTag the reference is OpenCV's DICT_APRILTAG_36h11,
// which reads the same prints). Writes docs/bench/vision_track.md.
//
// Usage: bench_vision_track [--frames N] [--out FILE]
// Timings are on one core (OpenCV single-threaded, AprilTag nthreads = 1), reported as
// ratios against the reference measured on the same frames. "Lost": markers the
// reference found in a frame and the tracker did not (the goal is 0).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/aruco.hpp>
#include <opencv2/core.hpp>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/vision/synthetic_camera.h"
#include "ddace/vision/tracker.h"
#include "results.h"

using namespace ddace::vision;

namespace {

constexpr int kRobots = 12;
constexpr double kBallSpeed = 0.8;

MarkerConfig sceneMarkers(DetectorBackend backend, bool ball) {
  MarkerConfig m;
  m.backend = backend;
  m.family = backend == DetectorBackend::Aruco ? "DICT_4X4_50" : "tag36h11";
  m.corner_size_m = 0.04;
  m.corners = {{0, {0.03, 0.03}}, {1, {0.77, 0.03}}, {2, {0.77, 0.57}}, {3, {0.03, 0.57}}};
  for (int i = 0; i < kRobots; ++i) {
    EntityMarker e;
    e.id = 10 + i;
    e.name = "R" + std::to_string(i + 1);
    e.size_m = 0.03;
    e.height_m = 0.035;
    m.entities.push_back(e);
  }
  if (ball) {
    EntityMarker e;
    e.id = 30;
    e.name = "ball";
    e.kind = ddace::task::EntityKind::Object;
    e.size_m = 0.03;
    e.height_m = 0.04;
    m.entities.push_back(e);
  }
  return m;
}

SyntheticCameraConfig sceneCamera() {
  SyntheticCameraConfig c;
  c.width = 1280;
  c.height = 720;
  c.position = {0.4, -0.15, 1.0};
  c.look_at = {0.4, 0.3};
  c.roll_deg = 3.0;
  c.light_gradient = 0.4;
  return c;
}

/// Robots on small circles (up to 0.09 m/s) in three rows; the ball between rows.
std::vector<TrueEntity> sceneTruth(double t, bool ball) {
  std::vector<TrueEntity> out;
  for (int i = 0; i < kRobots; ++i) {
    const double cx = 0.12 + 0.11 * (i % 6), cy = 0.13 + 0.34 * (i / 6);
    const double a = (1.0 + 0.2 * i) * t + i;
    out.push_back({"R" + std::to_string(i + 1), {cx + 0.03 * std::cos(a), cy + 0.03 * std::sin(a), a + M_PI / 2}});
  }
  if (ball) {
    const double s = std::fmod(kBallSpeed * t, 1.2);
    out.push_back({"ball", {s < 0.6 ? 0.1 + s : 0.7 - (s - 0.6), 0.30, 0.0}});
  }
  return out;
}

struct Result {
  double reference_ms = 0, tracker_ms = 0, full_ms = 0;
  long reference_found = 0, tracker_found = 0, lost = 0, frames = 0, roi_frames = 0;
  long ball_reference = 0, ball_tracker = 0;
  std::vector<double> errors_m;  // visible entities vs the truth
  double robot_side_px = 0;      // mean edge of the robots' markers in the image
  long robot_sides = 0;
};

/// `tuning`: the shipped config/tracker.yaml.
Result run(DetectorBackend backend, bool ball, int frames, const TrackerConfig& tuning) {
  const MarkerConfig markers = sceneMarkers(backend, ball);
  SyntheticCamera camera(sceneCamera(), markers);
  TrackerConfig tc = tuning;
  tc.markers = markers;
  Tracker tracker(tc);
  tracker.setCamera(camera.camera());
  DetectorConfig dc = tc.detector;  // the tracker's own detector on the whole frame
  dc.backend = markers.backend;
  dc.family = markers.family;
  auto full = makeDetector(dc);
  const auto dict = cv::aruco::getPredefinedDictionary(
      backend == DetectorBackend::Aruco ? cv::aruco::DICT_4X4_50 : cv::aruco::DICT_APRILTAG_36h11);
  const auto params = cv::aruco::DetectorParameters::create();

  Result res;
  for (int f = 0; f < frames; ++f) {
    const double t = f / 30.0;
    const auto truth = sceneTruth(t, ball);
    const cv::Mat img = camera.render(truth, t);
    auto t0 = ddace::SteadyClock::now();
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(img, dict, corners, ids, params);
    res.reference_ms += ddace::msSince(t0);
    t0 = ddace::SteadyClock::now();
    full->detect(img);
    res.full_ms += ddace::msSince(t0);
    t0 = ddace::SteadyClock::now();
    const FrameResult fr = tracker.process(img, t);
    res.tracker_ms += ddace::msSince(t0);
    res.roi_frames += !fr.full_frame;
    std::set<int> found;
    for (const auto& d : fr.detections) found.insert(d.id);
    res.tracker_found += static_cast<long>(found.size());
    for (const auto& d : fr.detections)
      if (d.id >= 10 && d.id < 10 + kRobots) {
        res.robot_side_px += d.sidePx();
        ++res.robot_sides;
      }
    for (int id : std::set<int>(ids.begin(), ids.end())) {
      if (!markers.isCorner(id) && !markers.entityById(id)) continue;
      ++res.reference_found;
      res.lost += !found.count(id);
      res.ball_reference += id == 30;
      res.ball_tracker += id == 30 && found.count(id);
    }
    for (size_t i = 0; i < fr.entities.size(); ++i)
      if (fr.entities[i].visible)
        res.errors_m.push_back(
            std::hypot(fr.entities[i].pose.x - truth[i].pose.x, fr.entities[i].pose.y - truth[i].pose.y));
    ++res.frames;
  }
  return res;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

}  // namespace

int main(int argc, char** argv) try {
  const std::filesystem::path repo = ddace::bench::repositoryFromArgs(argc, argv, {"config/tracker.yaml"});
  int frames = 300;
  std::string out;  // default: the repository's docs/bench/vision_track.md
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc) frames = std::atoi(argv[++i]);
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else {
      std::cerr << "usage: bench_vision_track [--repo DIR] [--frames N] [--out FILE]\n";
      return 2;
    }
  }
  if (frames < 1) {
    std::cerr << "bench_vision_track: --frames must be >= 1\n";
    return 2;
  }
  cv::setNumThreads(1);
  TrackerConfig tuning;
  const std::string tuning_file = (repo / "config" / "tracker.yaml").string();
  parseTrackerTuning(ddace::readTextFile(tuning_file), tuning_file, tuning);
  std::ostringstream md;
  md << "# The overhead tracker against OpenCV (bench_vision_track)\n\n"
     << "1280x720 frames of the synthetic overhead camera (tilted 9 degrees, rolled 3, 40 % light falloff, blur, "
        "noise), "
     << frames << " frames at 30 frames/s per scene and backend, one core, the tuning of config/tracker.yaml, "
     << "intrinsics given. *small*: 4 corner markers and " << kRobots
     << " robots with 3 cm markers on slow circles; *fast*: the same and a 3 cm ball passed across the table at "
     << kBallSpeed
     << " m/s (marker edges in the image: see the last column). *Reference*: OpenCV 4.6 `cv::aruco::detectMarkers` "
        "with its default parameters on "
     << "the whole frame (for AprilTag: its `DICT_APRILTAG_36h11`, the same prints). *Lost*: markers the reference "
        "found in a frame and the tracker did not. *Time ratio*: the tracker's mean time per frame (detection, "
        "table frame, poses, filtering; full-frame passes included) over the reference's, measured on the same "
        "frames. *Backend, full frame*: the tracker's detector (shipped tuning, corner refinement) on the whole "
        "frame, for the speed-up of the region search. Position errors: entities the tracker reports visible, "
        "against the true poses.\n\n"
     << "| scene | backend | reference (ms) | backend, full frame (ms) | tracker (ms) | tracker / reference | "
        "region frames | found by reference | lost | ball: reference / tracker | position p95 / max (mm) | "
        "robot marker edge (px) |\n"
     << "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  bool ok = true;
  for (const bool ball : {false, true})
    for (const DetectorBackend backend : {DetectorBackend::Aruco, DetectorBackend::AprilTag}) {
      const Result r = run(backend, ball, frames, tuning);
      char line[512];
      std::snprintf(line, sizeof line,
                    "| %s | %s | %.2f | %.2f | %.2f | %.2f | %ld / %ld | %ld | %ld | %s | %.2f / %.2f | %.1f |\n",
                    ball ? "fast" : "small", toString(backend).c_str(), r.reference_ms / r.frames, r.full_ms / r.frames,
                    r.tracker_ms / r.frames, r.tracker_ms / r.reference_ms, r.roi_frames, r.frames, r.reference_found,
                    r.lost,
                    ball ? (std::to_string(r.ball_reference) + " / " + std::to_string(r.ball_tracker)).c_str() : "-",
                    percentile(r.errors_m, 0.95) * 1000, percentile(r.errors_m, 1.0) * 1000,
                    r.robot_side_px / std::max(1L, r.robot_sides));
      md << line;
      std::cout << line << std::flush;
      ok = ok && r.reference_found > 0;
    }
  md << "\nGoal (issue 16): no marker lost that the reference finds, small markers and the fast ball included. "
        "The regions grow at `filter.max_speed` (1 m/s, about 5 cm a frame at 30 Hz with `gate_margin`) around "
        "every marker, which on this crowded table covers about half the image: the price of searching every "
        "position the filter accepts.\n\n"
     << "Written by `bench_vision_track` (`ddace bench vision_track`), " << ddace::utcNow() << ", load average "
     << ddace::loadAverage() << " while it ran.\n";
  if (out.empty()) {
    ddace::bench::writeResults(repo, "vision_track", md.str());
  } else {
    ddace::writeTextFile(out, md.str());
    std::cout << "wrote " << out << "\n";
  }
  return ok ? 0 : 1;
} catch (const std::exception& e) {
  std::cerr << "bench_vision_track: error: " << e.what() << "\n";
  return 1;
}
