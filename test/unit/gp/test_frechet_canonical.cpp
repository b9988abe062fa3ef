// Canonical frame, resampling by progress, discrete Fréchet distance and the spec's
// normalised FD.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>

#include "ddace/common/error.h"
#include "ddace/eval/frechet.h"
#include "ddace/gp/canonical.h"

using namespace ddace;
using Eigen::Vector2d;
using Path = std::vector<Vector2d>;

namespace {

/// Textbook recursive definition with a full memo table: the reference.
double frechetReference(const Path& p, const Path& q) {
  std::vector<std::vector<double>> ca(p.size(), std::vector<double>(q.size(), -1));
  std::function<double(size_t, size_t)> c = [&](size_t i, size_t j) -> double {
    if (ca[i][j] >= 0) return ca[i][j];
    const double d = (p[i] - q[j]).norm();
    double v;
    if (i == 0 && j == 0) v = d;
    else if (i == 0) v = std::max(c(0, j - 1), d);
    else if (j == 0) v = std::max(c(i - 1, 0), d);
    else v = std::max(std::min({c(i - 1, j), c(i - 1, j - 1), c(i, j - 1)}), d);
    return ca[i][j] = v;
  };
  return c(p.size() - 1, q.size() - 1);
}

Path arc(int n, double amplitude, const Vector2d& from, const Vector2d& to, bool uneven = false) {
  Path out;
  const Vector2d d = to - from, perp(-d.y(), d.x());
  for (int i = 0; i < n; ++i) {
    double u = static_cast<double>(i) / (n - 1);
    if (uneven) u = u * u * (3 - 2 * u);  // slow at the ends, like a robot accelerating
    out.push_back(from + u * d + amplitude * std::sin(M_PI * u) * perp);
  }
  return out;
}

}  // namespace

TEST(Frechet, TestVectors) {
  const Path line = {{0, 0}, {1, 0}, {2, 0}};
  EXPECT_DOUBLE_EQ(eval::frechetDistance(line, line), 0.0);
  EXPECT_DOUBLE_EQ(eval::frechetDistance(line, {{0, 1}, {1, 1}, {2, 1}}), 1.0);
  // Unequal lengths: every point of the longer path needs a partner.
  EXPECT_DOUBLE_EQ(eval::frechetDistance({{0, 0}, {1, 0}, {2, 0}, {3, 0}}, {{0, 0}, {3, 0}}), 1.0);
  EXPECT_DOUBLE_EQ(eval::frechetDistance({{0, 0}}, {{1, 0}, {0, 3}}), 3.0);
  // Direction matters (Hausdorff would be 0).
  EXPECT_DOUBLE_EQ(eval::frechetDistance({{0, 0}, {1, 1}, {2, 0}}, {{2, 0}, {1, 1}, {0, 0}}), 2.0);
  // Only vertices are coupled: q's middle points must wait at an end of p's long edge.
  EXPECT_DOUBLE_EQ(eval::frechetDistance({{0, 0}, {4, 0}}, {{0, 0}, {2, 0}, {2, 0.5}, {4, 0}}), std::sqrt(4.25));
}

TEST(Frechet, EqualsTheRecursiveDefinitionOnRandomPaths) {
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> len(1, 30);
  for (int trial = 0; trial < 200; ++trial) {
    Path p(len(gen)), q(len(gen));
    for (auto& v : p) v = {u(gen), u(gen)};
    for (auto& v : q) v = {u(gen), u(gen)};
    const double ref = frechetReference(p, q);
    EXPECT_DOUBLE_EQ(eval::frechetDistance(p, q), ref) << "trial " << trial;
    EXPECT_DOUBLE_EQ(eval::frechetDistance(q, p), ref) << "symmetry, trial " << trial;
  }
}

TEST(Frechet, RejectsEmptyPaths) {
  EXPECT_THROW(eval::frechetDistance({}, {{0, 0}}), Error);
  EXPECT_THROW(eval::frechetDistance({{0, 0}}, {}), Error);
  EXPECT_THROW(eval::normalisedFrechet({}, {{0, 0}, {1, 0}}), Error);
  // A ground truth that does not move has no canonical frame.
  EXPECT_THROW(eval::normalisedFrechet({{0, 0}, {1, 0}}, {{0.5, 0.5}, {0.5, 0.5}}), Error);
}

TEST(NormalisedFrechet, IgnoresSamplingRateAndSpeed) {
  const Path gt = arc(37, 0.2, {0.1, 0.2}, {0.7, 0.5}, true);
  const Path gen = arc(400, 0.2, {0.1, 0.2}, {0.7, 0.5});
  EXPECT_LT(eval::normalisedFrechet(gen, gt), 2e-3);
}

TEST(NormalisedFrechet, IsInUnitsOfTheGroundTruthLength) {
  // A parallel offset of 10 % of the start-goal distance, at any scale and direction.
  for (double scale : {0.05, 0.6, 3.0}) {
    for (double angle : {0.0, 1.0, -2.5}) {
      const Vector2d dir(std::cos(angle), std::sin(angle)), perp(-dir.y(), dir.x());
      const Vector2d s(0.3, -0.2), g = s + scale * dir;
      Path gt, gen;
      for (int i = 0; i <= 50; ++i) {
        gt.push_back(s + (i / 50.0) * (g - s));
        gen.push_back(s + (i / 50.0) * (g - s) + 0.1 * scale * perp);
      }
      EXPECT_NEAR(eval::normalisedFrechet(gen, gt), 0.1, 1e-9);
    }
  }
}

TEST(CanonicalFrame, MapsStartToOriginAndEndToUnitX) {
  const gp::CanonicalFrame f({0.2, 0.4}, {0.2, 0.9});
  EXPECT_TRUE(f.toCanonical(Vector2d(0.2, 0.4)).isApprox(Vector2d(0, 0)));
  EXPECT_TRUE(f.toCanonical(Vector2d(0.2, 0.9)).isApprox(Vector2d(1, 0)));
  // Left of the direction of travel is +y.
  EXPECT_TRUE(f.toCanonical(Vector2d(0.1, 0.4)).isApprox(Vector2d(0, 0.2)));
  EXPECT_NEAR(f.scale(), 0.5, 1e-15);
  EXPECT_NEAR(f.angle(), M_PI / 2, 1e-15);
  const Vector2d p(0.77, -0.3);
  EXPECT_TRUE(f.fromCanonical(f.toCanonical(p)).isApprox(p, 1e-14));
  EXPECT_THROW(gp::CanonicalFrame({1, 1}, {1, 1}), Error);
}

TEST(Resample, EquallySpacedInArcLengthWithExactEnds) {
  // A straight path sampled unevenly.
  const Path p = {{0, 0}, {0.1, 0}, {0.15, 0}, {0.9, 0}, {1.0, 0}};
  const Path r = gp::resampleByProgress(p, 11);
  ASSERT_EQ(r.size(), 11u);
  for (int i = 0; i < 11; ++i) EXPECT_NEAR(r[i].x(), i / 10.0, 1e-12);
  EXPECT_EQ(r.front(), p.front());
  EXPECT_EQ(r.back(), p.back());
  // A path that stands still.
  const Path still = gp::resampleByProgress({{0.3, 0.3}, {0.3, 0.3}}, 5);
  for (const auto& v : still) EXPECT_EQ(v, Vector2d(0.3, 0.3));
  // An L-shaped path: the corner is at progress 1/2.
  const Path l = gp::resampleByProgress({{0, 0}, {1, 0}, {1, 1}}, 3);
  EXPECT_TRUE(l[1].isApprox(Vector2d(1, 0)));
  EXPECT_THROW(gp::resampleByProgress({}, 5), Error);
  EXPECT_THROW(gp::resampleByProgress(p, 1), Error);
}
