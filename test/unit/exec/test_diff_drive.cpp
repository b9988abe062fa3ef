// The unicycle model of a Hamster: kinematics, limits, latency, watchdog, noise.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/error.h"
#include "ddace/exec/diff_drive.h"

using namespace ddace;
using namespace ddace::exec;

namespace {

/// Runs `seconds` of simulation, re-sending `w` every cycle.
void drive(DiffDriveModel& m, WheelSpeeds w, double seconds) {
  const int n = static_cast<int>(std::round(seconds * m.params().rate_hz));
  for (int i = 0; i < n; ++i) {
    m.command(w, m.time());
    m.step();
  }
}

}  // namespace

TEST(DiffDrive, StraightLineAtCommandedSpeed) {
  DiffDriveParams p;
  DiffDriveModel m(p, {0.1, 0.2, M_PI / 2});
  drive(m, {0.1, 0.1}, 1.0);
  EXPECT_NEAR(m.truePose().x, 0.1, 1e-9);
  EXPECT_NEAR(m.truePose().y, 0.3, 1e-9);
  EXPECT_NEAR(m.truePose().yaw, M_PI / 2, 1e-9);
}

TEST(DiffDrive, OppositeWheelsTurnOnTheSpot) {
  DiffDriveParams p;
  p.wheel_base_m = 0.03;
  DiffDriveModel m(p);
  // w = (vr - vl) / b = 0.03 / 0.03 = 1 rad/s for pi/2 seconds.
  drive(m, {-0.015, 0.015}, 0.5);
  EXPECT_NEAR(m.truePose().yaw, 0.5, 1e-9);
  EXPECT_NEAR(m.truePose().x, 0.0, 1e-12);
  EXPECT_NEAR(m.truePose().y, 0.0, 1e-12);
}

TEST(DiffDrive, ArcIntegrationStaysOnTheCircle) {
  DiffDriveParams p;
  p.rate_hz = 10;  // coarse on purpose: exact arcs do not drift outward
  DiffDriveModel m(p);
  const double v = 0.1, w = 2.0;  // radius 0.05 m around (0, 0.05)
  drive(m, twistToWheels(v, w, p.wheel_base_m), 2.0);
  const double r = std::hypot(m.truePose().x, m.truePose().y - v / w);
  EXPECT_NEAR(r, v / w, 1e-9);
}

TEST(DiffDrive, WheelSpeedsAreClamped) {
  DiffDriveParams p;
  p.max_wheel_speed_mps = 0.1;
  DiffDriveModel m(p);
  drive(m, {5.0, 5.0}, 1.0);
  EXPECT_NEAR(m.truePose().x, 0.1, 1e-9);
  EXPECT_DOUBLE_EQ(m.applied().left_mps, 0.1);
}

TEST(DiffDrive, NonFiniteCommandStopsTheWheels) {
  DiffDriveModel m(DiffDriveParams{});
  m.command({std::nan(""), 0.1}, 0);
  m.step();
  EXPECT_EQ(m.applied().left_mps, 0.0);
}

TEST(DiffDrive, CommandLatencyDelaysMotion) {
  DiffDriveParams p;
  p.latency_s = 0.1;  // 5 cycles at 50 Hz
  DiffDriveModel m(p);
  m.command({0.1, 0.1}, 0.0);
  for (int i = 0; i < 5; ++i) {
    m.step();
    EXPECT_EQ(m.truePose().x, 0.0) << "moved before the latency elapsed, cycle " << i;
  }
  m.step();
  EXPECT_GT(m.truePose().x, 0.0);
}

TEST(DiffDrive, WatchdogStopsWhenCommandsStop) {
  DiffDriveParams p;
  p.command_timeout_s = 0.2;
  DiffDriveModel m(p);
  m.command({0.1, 0.1}, 0.0);
  for (int i = 0; i < 50; ++i) m.step();  // 1 s without a new command
  EXPECT_TRUE(m.applied().isZero());
  // It moved at most for the timeout (+ one cycle).
  EXPECT_LE(m.truePose().x, 0.1 * (0.2 + 0.02) + 1e-9);
  EXPECT_GT(m.truePose().x, 0.0);
}

TEST(DiffDrive, StalledRobotDoesNotMove) {
  DiffDriveModel m(DiffDriveParams{});
  m.setStalled(true);
  drive(m, {0.1, 0.1}, 1.0);
  EXPECT_EQ(m.truePose().x, 0.0);
  EXPECT_FALSE(m.applied().isZero());
}

TEST(DiffDrive, MeasurementNoiseHasTheConfiguredSpread) {
  DiffDriveParams p;
  p.position_noise_m = 0.005;
  p.yaw_noise_rad = 0.02;
  DiffDriveModel m(p, {0.5, 0.5, 0});
  double sx = 0, sxx = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double x = m.measuredPose().x - 0.5;
    sx += x;
    sxx += x * x;
  }
  EXPECT_NEAR(sx / n, 0.0, 3 * 0.005 / std::sqrt(n) + 1e-6);
  EXPECT_NEAR(std::sqrt(sxx / n), 0.005, 0.0003);
  EXPECT_EQ(m.truePose().x, 0.5);
}

TEST(DiffDrive, InvalidParametersAreRefusedByName) {
  DiffDriveParams p;
  p.wheel_base_m = 0;
  try {
    DiffDriveModel m(p);
    FAIL() << "accepted a zero wheel base";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("wheel_base_m"), std::string::npos) << e.what();
  }
  p = {};
  p.latency_s = -1;
  EXPECT_THROW(DiffDriveModel{p}, Error);
}
