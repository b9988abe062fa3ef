// The tracker end to end on synthetic camera images: poses within 5 mm and 3 degrees of
// the truth, through light changes, blur, noise and a hand over a robot.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/error.h"
#include "ddace/vision/synthetic_camera.h"
#include "ddace/vision/tracker.h"

using namespace ddace::vision;

namespace {

const std::string kConfig = std::string(DDACE_SOURCE_DIR) + "/config/";
const std::string kData = std::string(DDACE_TEST_DATA_DIR) + "/vision/";

/// R1..R4 driving on small circles, G1 fixed, at time t.
std::vector<TrueEntity> scene(double t) {
  std::vector<TrueEntity> out;
  for (int i = 0; i < 4; ++i) {
    const double a = (0.8 + 0.3 * i) * t + i;
    const double cx = 0.2 + 0.2 * i, cy = 0.3 + 0.15 * (i % 2);
    out.push_back({"R" + std::to_string(i + 1), {cx + 0.08 * std::cos(a), cy + 0.08 * std::sin(a), wrapAngle(a + M_PI / 2)}});
  }
  out.push_back({"G1", {0.85, 0.8, 0.0}});
  return out;
}

struct Errors {
  double max_pos_m = 0, max_yaw_rad = 0;
  int compared = 0;
};

void accumulate(Errors& e, const FrameResult& fr, const std::vector<TrueEntity>& truth, bool only_visible = true) {
  for (const auto& s : fr.entities) {
    if (only_visible && !s.visible) continue;
    for (const auto& t : truth)
      if (t.name == s.name) {
        e.max_pos_m = std::max(e.max_pos_m, std::hypot(s.pose.x - t.pose.x, s.pose.y - t.pose.y));
        if (s.name[0] != 'G') e.max_yaw_rad = std::max(e.max_yaw_rad, std::abs(wrapAngle(s.pose.yaw - t.pose.yaw)));
        ++e.compared;
      }
  }
}

TrackerConfig shippedConfig() { return loadTrackerConfig(kConfig + "markers.yaml", kConfig + "tracker.yaml"); }

}  // namespace

TEST(TrackerConfig, ShippedFilesLoad) {
  const TrackerConfig c = shippedConfig();
  EXPECT_EQ(c.markers.corners.size(), 4u);
  ASSERT_EQ(c.markers.entities.size(), 5u);
  EXPECT_EQ(c.markers.entities[0].name, "R1");
  EXPECT_EQ(c.markers.entities[4].kind, ddace::task::EntityKind::Goal);
  EXPECT_DOUBLE_EQ(c.markers.entities[0].height_m, 0.035);
  EXPECT_DOUBLE_EQ(c.markers.entities[4].height_m, 0.0);
  EXPECT_EQ(c.roi.full_frame_every, 15);
  EXPECT_NO_THROW(loadSyntheticCameraConfig(kData + "synthetic_camera.yaml"));
}

TEST(TrackerConfig, ErrorsNameFileLineAndColumn) {
  auto firstError = [](const std::string& text) {
    try {
      parseMarkerConfig(text, "m.yaml");
    } catch (const ddace::Error& e) {
      return e.diagnostics().front().str();
    }
    return std::string("no error");
  };
  EXPECT_EQ(firstError("family: DICT_4X4_50\nentities:\n  - {id: 1, name: R1}\n  - {id: 1, name: R2}\n"),
            "m.yaml:4:10: marker id 1 is used twice");
  EXPECT_EQ(firstError("entities:\n  - {id: 60, name: R1}\n"), "m.yaml:2:10: marker id 60 is outside DICT_4X4_50 (ids 0..49)");
  EXPECT_NE(firstError("entities:\n  - {id: 1, name: R1, colour: red}\n").find("m.yaml:2:23: unknown key 'colour'"),
            std::string::npos);
  EXPECT_NE(firstError("corners:\n  - {id: 0, x: 0, y: 0}\nentities:\n  - {id: 1, name: R1}\n").find("exactly four"),
            std::string::npos);
  EXPECT_NE(firstError("entities:\n  - {id: 1, name: 1R}\n").find("m.yaml:2:19: entity name '1R'"), std::string::npos);
  EXPECT_NE(firstError("entities: [\n").find("m.yaml:"), std::string::npos);
  EXPECT_NE(firstError("entities:\n  - {id: 1, name: R1, kind: robit}\n").find("kind must be robot, object or goal"),
            std::string::npos);
  TrackerConfig c;
  try {
    parseTrackerTuning("roi:\n  full_frame_every: 0\n", "t.yaml", c);
    FAIL() << "no error";
  } catch (const ddace::Error& e) {
    EXPECT_EQ(e.diagnostics().front().str(), "t.yaml:2:21: 'full_frame_every' = 0 is out of range [1, 100000]");
  }
  EXPECT_THROW(loadMarkerConfig(kData + "does_not_exist.yaml"), ddace::Error);
}

TEST(TableFrame, CornerMarkersGiveTheTrueTableFrame) {
  const TrackerConfig c = shippedConfig();
  SyntheticCamera cam(loadSyntheticCameraConfig(kData + "synthetic_camera.yaml"), c.markers);
  const cv::Mat img = cam.render({}, 0.0);
  auto det = makeDetector(c.detector);
  const auto frame = TableFrame::fromCornerMarkers(det->detect(img), c.markers.corners);
  ASSERT_TRUE(frame.has_value());
  for (double x = 0.0; x <= 1.0; x += 0.25)
    for (double y = 0.0; y <= 1.0; y += 0.25) {
      const cv::Point2d p = frame->imageToTable(cam.project({x, y, 0}));
      EXPECT_LT(std::hypot(p.x - x, p.y - y), 0.0015) << x << " " << y;
    }
  // With the intrinsics, the homography gives the camera centre (for parallax correction).
  TableFrame f = *frame;
  ASSERT_TRUE(f.setIntrinsics(cam.camera().K));
  const cv::Vec3d C = *f.cameraCenter();
  EXPECT_LT(cv::norm(C - cam.config().position), 0.01) << C;
  // Missing one corner: no frame.
  auto dets = det->detect(img);
  dets.erase(std::remove_if(dets.begin(), dets.end(), [](const Detection& d) { return d.id == 2; }), dets.end());
  EXPECT_FALSE(TableFrame::fromCornerMarkers(dets, c.markers.corners).has_value());
}

TEST(TableFrame, MarkerPoseGivesYawCounterClockwiseFromTableX) {
  // An ideal top-down camera: 1 px = 1 mm, image y = -table y.
  TableFrame f = TableFrame::fromCameraPose(cv::Matx33d(1000, 0, 500, 0, 1000, 500, 0, 0, 1),
                                            cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1), cv::Vec3d(-0.5, 0.5, 1.0));
  for (double yaw : {0.0, 0.5, 1.6, -2.9, 3.1}) {
    Detection d;
    const double h = 15, c = std::cos(yaw), s = std::sin(yaw);
    const double local[4][2] = {{-h, h}, {h, h}, {h, -h}, {-h, -h}};  // printed TL, TR, BR, BL (mm, y up)
    for (int k = 0; k < 4; ++k) {
      const cv::Point2d p = f.tableToImage({0.3 + (c * local[k][0] - s * local[k][1]) / 1000,
                                            0.6 + (s * local[k][0] + c * local[k][1]) / 1000});
      d.corners[k] = cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y));
    }
    const PlanarPose p = f.markerPose(d);
    EXPECT_NEAR(p.x, 0.3, 1e-4);
    EXPECT_NEAR(p.y, 0.6, 1e-4);
    EXPECT_NEAR(wrapAngle(p.yaw - yaw), 0.0, 1e-3) << yaw;
  }
  // Camera below the table, and camera above it looking up.
  EXPECT_THROW(TableFrame::fromCameraPose(cv::Matx33d::eye(), cv::Matx33d::eye(), cv::Vec3d(0, 0, 1)), ddace::Error);
  EXPECT_THROW(TableFrame::fromCameraPose(cv::Matx33d::eye(), cv::Matx33d::eye(), cv::Vec3d(0, 0, -1)), ddace::Error);
}

TEST(Tracker, PosesWithin5mmAnd3DegreesOfTheTruth) {
  for (const std::string backend : {"aruco", "apriltag"}) {
    TrackerConfig c = shippedConfig();
    if (backend == "apriltag") {
      c.markers.backend = "apriltag";
      c.markers.family = "tag36h11";
    }
    auto cam_cfg = loadSyntheticCameraConfig(kData + "synthetic_camera.yaml");
    cam_cfg.occlusions.clear();
    SyntheticCamera cam(cam_cfg, c.markers);
    Tracker tracker(c);
    tracker.setCamera(cam.camera());
    Errors e;
    for (int f = 0; f < 90; ++f) {
      const double t = f / 30.0;
      const auto truth = scene(t);
      const FrameResult fr = tracker.process(cam.render(truth, t), t);
      ASSERT_TRUE(fr.table_valid) << backend;
      for (const auto& s : fr.entities) EXPECT_TRUE(s.visible) << backend << " " << s.name << " frame " << f;
      accumulate(e, fr, truth);
    }
    EXPECT_EQ(e.compared, 90 * 5) << backend;
    EXPECT_LT(e.max_pos_m, 0.005) << backend;
    EXPECT_LT(e.max_yaw_rad, 3.0 * M_PI / 180) << backend;
    std::printf("%s: max position error %.2f mm, max yaw error %.2f deg\n", backend.c_str(), e.max_pos_m * 1000,
                e.max_yaw_rad * 180 / M_PI);
  }
}

TEST(Tracker, ParallaxOfRaisedMarkersIsCorrectedWithIntrinsics) {
  TrackerConfig c = shippedConfig();
  auto cam_cfg = loadSyntheticCameraConfig(kData + "synthetic_camera.yaml");
  SyntheticCamera cam(cam_cfg, c.markers);
  // R4 far from the camera's nadir: without intrinsics the 3.5 cm height shows.
  const std::vector<TrueEntity> truth = {{"R4", {0.9, 0.95, 0.0}}};
  Tracker with(c), without(c);
  with.setCamera(cam.camera());
  const cv::Mat img = cam.render(truth, 0.0);
  const auto a = with.process(img, 0.0).entities[3].pose;
  const auto b = without.process(img, 0.0).entities[3].pose;
  EXPECT_LT(std::hypot(a.x - 0.9, a.y - 0.95), 0.003);
  EXPECT_GT(std::hypot(b.x - 0.9, b.y - 0.95), 0.015);
}

TEST(Tracker, HoldsThroughAHalfSecondOcclusionThenGoesStale) {
  TrackerConfig c = shippedConfig();
  auto cam_cfg = loadSyntheticCameraConfig(kData + "synthetic_camera.yaml");  // R2 hidden 1.0 .. 1.5 s
  SyntheticCamera cam(cam_cfg, c.markers);
  Tracker tracker(c);
  tracker.setCamera(cam.camera());
  int hidden_frames = 0;
  PlanarPose before;
  for (int f = 0; f < 75; ++f) {
    const double t = f / 30.0;
    const auto truth = scene(t);
    const FrameResult fr = tracker.process(cam.render(truth, t), t);
    const EntityState& r2 = fr.entities[1];
    ASSERT_EQ(r2.name, "R2");
    const bool hidden = cam.occluded("R2", t);
    if (!hidden) {
      EXPECT_TRUE(r2.visible) << "frame " << f;
      EXPECT_LT(std::hypot(r2.pose.x - truth[1].pose.x, r2.pose.y - truth[1].pose.y), 0.005) << "frame " << f;
      before = r2.pose;
    } else {
      ++hidden_frames;
      EXPECT_FALSE(r2.visible) << "frame " << f;
      EXPECT_FALSE(r2.stale) << "frame " << f;  // hold (1 s) > occlusion (0.5 s)
      EXPECT_DOUBLE_EQ(r2.pose.x, before.x);      // held, not extrapolated
    }
    EXPECT_TRUE(fr.entities[0].visible) << "R1 must stay visible, frame " << f;
  }
  EXPECT_EQ(hidden_frames, 15);
  // Hidden for longer than the hold: stale.
  cam_cfg.occlusions = {{"R3", 0.0, 10.0}};
  SyntheticCamera cam2(cam_cfg, c.markers);
  Tracker t2(c);
  FrameResult fr;
  for (int f = 0; f < 40; ++f) fr = t2.process(cam2.render(scene(f / 30.0), f / 30.0), f / 30.0);
  EXPECT_TRUE(fr.entities[2].stale);
  EXPECT_FALSE(fr.entities[2].visible);
  EXPECT_FALSE(fr.entities[0].stale);
}

TEST(Tracker, RegionSearchGivesTheSamePosesAsFullFrames) {
  TrackerConfig roi = shippedConfig();
  TrackerConfig full = roi;
  full.roi.enabled = false;
  auto cam_cfg = loadSyntheticCameraConfig(kData + "synthetic_camera.yaml");
  cam_cfg.occlusions.clear();
  SyntheticCamera cam(cam_cfg, roi.markers);
  Tracker a(roi), b(full);
  int roi_frames = 0;
  for (int f = 0; f < 45; ++f) {
    const double t = f / 30.0;
    const cv::Mat img = cam.render(scene(t), t);
    const FrameResult ra = a.process(img, t), rb = b.process(img, t);
    roi_frames += !ra.full_frame;
    EXPECT_TRUE(rb.full_frame);
    EXPECT_EQ(ra.full_frame, f % 15 == 0) << f;
    if (!ra.full_frame) {
      EXPECT_FALSE(ra.rois.empty());
    }
    ASSERT_EQ(ra.detections.size(), rb.detections.size()) << "frame " << f;
    for (size_t i = 0; i < ra.entities.size(); ++i) {
      EXPECT_NEAR(ra.entities[i].pose.x, rb.entities[i].pose.x, 1e-4);
      EXPECT_NEAR(ra.entities[i].pose.y, rb.entities[i].pose.y, 1e-4);
    }
  }
  EXPECT_EQ(roi_frames, 42);
}

TEST(Tracker, MergeRegionsJoinsOverlapsOnly) {
  const auto m = mergeRegions({{0, 0, 10, 10}, {5, 5, 10, 10}, {30, 30, 5, 5}, {14, 14, 2, 2}});
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], cv::Rect(0, 0, 16, 16));
  EXPECT_EQ(m[1], cv::Rect(30, 30, 5, 5));
}
