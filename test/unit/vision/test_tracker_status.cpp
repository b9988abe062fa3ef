// The tracker node's rules: its health (what it reports on /diagnostics) and the time
// line of a video file.
#include <gtest/gtest.h>

#include "ddace/vision/tracker.h"

using namespace ddace::vision;
using Level = TrackerStatus::Level;

namespace {

FrameResult tracking() {
  FrameResult fr;
  fr.table_valid = true;
  fr.table_reprojection_px = 0.4;
  fr.height_correction = HeightCorrection::On;
  EntityState seen, held;
  seen.visible = true;
  seen.stale = false;
  held.visible = false;
  held.stale = true;
  fr.entities = {seen, seen, held};
  return fr;
}

}  // namespace

TEST(TrackerStatus, OkWhileTrackingWithHeightCorrection) {
  const TrackerStatus s = trackerStatus(tracking(), std::nullopt, 2.0);
  EXPECT_EQ(s.level, Level::Ok);
  EXPECT_EQ(s.summary, "tracking");
  EXPECT_EQ(s.visible, 2);
  EXPECT_EQ(s.stale, 1);
}

TEST(TrackerStatus, WarnsBeforeTheFirstFrame) {
  const TrackerStatus s = trackerStatus(std::nullopt, std::nullopt, 2.0);
  EXPECT_EQ(s.level, Level::Warn);
  EXPECT_EQ(s.summary, "no frame yet");
}

TEST(TrackerStatus, NoTableFrameIsAnErrorThatSaysWhy) {
  FrameResult fr = tracking();
  fr.table_valid = false;
  EXPECT_EQ(trackerStatus(fr, std::nullopt, 2.0).level, Level::Error);
  EXPECT_EQ(trackerStatus(fr, std::nullopt, 2.0).summary, "no table frame: not all four corner markers are visible");
  fr.table_refused = true;
  fr.table_reprojection_px = 3.25;
  const TrackerStatus s = trackerStatus(fr, std::nullopt, 2.0);
  EXPECT_EQ(s.level, Level::Error);
  EXPECT_EQ(s.summary.rfind("table frame refused: reprojection error 3.25 px > table.max_reprojection_px 2.00", 0), 0u)
      << s.summary;
}

TEST(TrackerStatus, MissingHeightCorrectionWarnsWithTheErrorItCosts) {
  FrameResult fr = tracking();
  fr.height_correction = HeightCorrection::NoIntrinsics;
  ParallaxEstimate p;
  p.max_error_m = 0.0214;
  TrackerStatus s = trackerStatus(fr, p, 2.0);
  EXPECT_EQ(s.level, Level::Warn);
  EXPECT_EQ(s.summary, "height correction off: no intrinsics (up to 21 mm)");
  fr.height_correction = HeightCorrection::IntrinsicsDoNotFit;
  s = trackerStatus(fr, std::nullopt, 2.0);
  EXPECT_EQ(s.level, Level::Warn);
  EXPECT_EQ(s.summary, "height correction off: the intrinsics do not fit the table frame");
}

TEST(TrackerStatus, ARefusedFitWithAnOlderTableFrameKeptIsAWarning) {
  FrameResult fr = tracking();
  fr.table_refused = true;
  fr.table_reprojection_px = 5.0;
  const TrackerStatus s = trackerStatus(fr, std::nullopt, 2.0);
  EXPECT_EQ(s.level, Level::Warn);
  EXPECT_NE(s.summary.find("table frame refused"), std::string::npos);
}

TEST(VideoTimeline, FramesKeepTheFilesIntervalsWhateverThePlaybackRate) {
  VideoTimeline t;
  // The first frame (0.5 s into the file) is read at 1000 s: the file's t = 0 is 999.5 s.
  EXPECT_DOUBLE_EQ(t.stamp(0.5, 1000.0), 1000.0);
  // Read slowly (a loaded machine) or quickly: the stamps follow the file, not the reads.
  EXPECT_DOUBLE_EQ(t.stamp(0.5 + 1.0 / 30, 1000.2), 1000.0 + 1.0 / 30);
  EXPECT_DOUBLE_EQ(t.stamp(2.5, 1000.3), 1002.0);
}
