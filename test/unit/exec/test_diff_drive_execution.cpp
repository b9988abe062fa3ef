// The simulator's differential-drive execution model: the ROS stack's control law on a
// unicycle, with measurement noise.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/eval/frechet.h"
#include "ddace/exec/diff_drive_execution.h"

using namespace ddace::exec;

namespace {
Path arc(Eigen::Vector2d a, Eigen::Vector2d b, double bulge) {
  Path p;
  const Eigen::Vector2d d = b - a, n(-d.y(), d.x());
  for (int i = 0; i <= 100; ++i) {
    const double u = i / 100.0;
    p.push_back(a + u * d + bulge * std::sin(M_PI * u) * n);
  }
  return p;
}
}  // namespace

TEST(DiffDriveExecution, RobotsArriveWellInsideTheRadiusEvenWithNoise) {
  for (double noise : {0.0, 0.005}) {
    DiffDriveExecution model(0.03, noise, 7);
    const Path planned = arc({0.1, 0.2}, {0.6, 0.5}, 0.25);
    const Path done = model.follow(planned, true, 0);
    EXPECT_LT((done.back() - planned.back()).norm(), 0.03) << noise;
    // It followed the curve, not a straight line to the goal.
    EXPECT_LT(ddace::eval::normalisedFrechet(done, planned), 0.1) << noise;
    EXPECT_GT(done.size(), 50u);
  }
}

TEST(DiffDriveExecution, ObjectsAreCarriedIdeally) {
  DiffDriveExecution model(0.03, 0.005, 7);
  const Path planned = arc({0.1, 0.2}, {0.6, 0.5}, 0.1);
  EXPECT_EQ(model.follow(planned, false, 3), planned);
}

TEST(DiffDriveExecution, HeadingCarriesOverBetweenSegments) {
  // Turning back: the second segment starts facing away from it, so it takes longer than
  // the same segment for a fresh robot that starts facing along its path.
  DiffDriveExecution model(0.03, 0.0, 1);
  const Path out = arc({0.1, 0.5}, {0.5, 0.5}, 0.0);
  const Path back = arc({0.5, 0.5}, {0.1, 0.5}, 0.0);
  model.follow(out, true, 0);
  const size_t turning = model.follow(back, true, 0).size();
  DiffDriveExecution fresh(0.03, 0.0, 1);
  EXPECT_GT(turning, fresh.follow(back, true, 0).size());
}
