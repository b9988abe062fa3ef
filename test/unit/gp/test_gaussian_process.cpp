// GP regression: the repeated-input reduction equals the textbook likelihood and
// gradient, the gradient is the derivative, and scikit-learn parity on stored fixtures.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <random>

#include "ddace/common/repository.h"
#include "ddace/common/error.h"
#include "ddace/gp/gaussian_process.h"

using namespace ddace;
using gp::GaussianProcess;
using gp::RepeatedData;

namespace {

/// `segments` noisy copies of an arc on the same `points` inputs (a primitive's structure),
/// plus a few inputs seen only once, so the counts are not all equal.
void repeatedData(int segments, int points, Eigen::VectorXd& x, Eigen::VectorXd& y, bool singles = true) {
  std::mt19937 gen(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<double> xs, ys;
  for (int k = 0; k < segments; ++k) {
    const double a = 0.3 + 0.01 * k;
    for (int i = 0; i < points; ++i) {
      const double s = static_cast<double>(i) / (points - 1);
      xs.push_back(s);
      ys.push_back(a * std::sin(M_PI * s) + noise(gen));
    }
  }
  for (double s : singles ? std::vector<double>{0.013, 0.5123, 0.977} : std::vector<double>{}) {
    xs.push_back(s);
    ys.push_back(0.3 * std::sin(M_PI * s));
  }
  x = Eigen::Map<Eigen::VectorXd>(xs.data(), xs.size());
  y = Eigen::Map<Eigen::VectorXd>(ys.data(), ys.size());
}

Eigen::VectorXd vec(const YAML::Node& n) {
  Eigen::VectorXd v(n.size());
  for (size_t i = 0; i < n.size(); ++i) v[i] = n[i].as<double>();
  return v;
}

gp::Bounds bounds(const YAML::Node& n) {
  return {n[0].as<double>(), n[1].as<double>()};
}

}  // namespace

TEST(RepeatedData, GroupsExactlyEqualInputs) {
  Eigen::VectorXd x(5), y(5);
  x << 0.5, 0.0, 0.5, 1.0, 0.5;
  y << 1.0, 2.0, 3.0, 4.0, 5.0;
  const RepeatedData d = RepeatedData::group(x, y);
  ASSERT_EQ(d.inputs.size(), 3);
  EXPECT_EQ(d.inputs[1], 0.5);
  EXPECT_EQ(d.counts[1], 3.0);
  EXPECT_DOUBLE_EQ(d.means[1], 3.0);
  EXPECT_DOUBLE_EQ(d.residual_ss, 8.0);  // (1-3)^2 + 0 + (5-3)^2
  EXPECT_EQ(d.total, 5.0);
}

TEST(RepeatedData, RejectsBadData) {
  EXPECT_THROW(RepeatedData::group(Eigen::VectorXd(0), Eigen::VectorXd(0)), Error);
  EXPECT_THROW(RepeatedData::group(Eigen::VectorXd::Zero(3), Eigen::VectorXd::Zero(2)), Error);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(2);
  y[1] = std::nan("");
  EXPECT_THROW(RepeatedData::group(Eigen::VectorXd::Zero(2), y), Error);
}

TEST(Reduction, LikelihoodAndGradientEqualTheNaiveComputation) {
  Eigen::VectorXd x, y;
  repeatedData(6, 40, x, y);  // 243 observations on 43 distinct inputs
  const RepeatedData d = RepeatedData::group(x, y);
  ASSERT_EQ(d.inputs.size(), 43);
  for (bool use_constant : {true, false}) {
    for (const gp::KernelParams& p :
         {gp::KernelParams{0.2, 0.3, 1e-4}, gp::KernelParams{1.5, 0.05, 0.02}, gp::KernelParams{0.01, 2.0, 1e-6}}) {
      const Eigen::VectorXd theta = gp::toTheta(p, use_constant);
      Eigen::VectorXd g_fast, g_naive;
      const double fast = gp::logMarginalLikelihood(d, theta, use_constant, 1e-10, &g_fast);
      const double naive = gp::logMarginalLikelihoodNaive(x, y, theta, use_constant, 1e-10, &g_naive);
      ASSERT_TRUE(std::isfinite(naive));
      EXPECT_NEAR(fast, naive, 1e-8 * std::abs(naive)) << "C " << p.constant << " l " << p.length_scale;
      ASSERT_EQ(g_fast.size(), g_naive.size());
      for (Eigen::Index j = 0; j < g_fast.size(); ++j)
        EXPECT_NEAR(g_fast[j], g_naive[j], 1e-6 * (1 + std::abs(g_naive[j]))) << "component " << j;
    }
  }
}

TEST(Reduction, ToeplitzSolverEqualsCholeskyAndNaive) {
  // A primitive's structure: equally spaced progress values, every segment on all of them.
  Eigen::VectorXd x, y;
  repeatedData(5, 60, x, y, false);
  const RepeatedData d = RepeatedData::group(x, y);
  ASSERT_TRUE(gp::isToeplitz(d));
  Eigen::VectorXd x2, y2;
  repeatedData(5, 60, x2, y2, true);
  EXPECT_FALSE(gp::isToeplitz(RepeatedData::group(x2, y2)));
  // Including badly conditioned covariances: long length scales, tiny noise. At a
  // condition number of ~1e10 (C = 50) the Toeplitz solver is accurate to ~1e-6; beyond
  // 1e11 (C = 100, 20 per input) Auto must use Cholesky.
  struct Case {
    gp::KernelParams p;
    double tol;
  };
  for (const Case& c : {Case{{0.2, 0.3, 1e-4}, 1e-8}, Case{{1.5, 0.05, 0.02}, 1e-8}, Case{{0.13, 0.07, 1.2e-5}, 1e-8},
                        Case{{0.1, 2.0, 1e-6}, 1e-8}, Case{{50, 10, 1e-6}, 1e-6}}) {
    const Eigen::VectorXd theta = gp::toTheta(c.p, true);
    Eigen::VectorXd g_t, g_c, g_n;
    const double t = gp::logMarginalLikelihood(d, theta, true, 1e-10, &g_t, gp::Solver::Toeplitz);
    const double ch = gp::logMarginalLikelihood(d, theta, true, 1e-10, &g_c, gp::Solver::Cholesky);
    const double n = gp::logMarginalLikelihoodNaive(x, y, theta, true, 1e-10, &g_n);
    ASSERT_TRUE(std::isfinite(t)) << "l " << c.p.length_scale;
    EXPECT_NEAR(t, ch, c.tol * std::abs(ch)) << "l " << c.p.length_scale;
    EXPECT_NEAR(t, n, c.tol * std::abs(n)) << "l " << c.p.length_scale;
    for (Eigen::Index j = 0; j < 3; ++j) {
      EXPECT_NEAR(g_t[j], g_c[j], 100 * c.tol * (1 + std::abs(g_c[j]))) << "component " << j;
      EXPECT_NEAR(g_t[j], g_n[j], 100 * c.tol * (1 + std::abs(g_n[j]))) << "component " << j;
    }
  }
  Eigen::VectorXd x20, y20;
  repeatedData(20, 60, x20, y20, false);
  const RepeatedData d20 = RepeatedData::group(x20, y20);
  const Eigen::VectorXd extreme = gp::toTheta({100, 10, 1e-6}, true);
  EXPECT_EQ(gp::logMarginalLikelihood(d20, extreme, true, 1e-10),
            gp::logMarginalLikelihood(d20, extreme, true, 1e-10, nullptr, gp::Solver::Cholesky));
  EXPECT_THROW(gp::logMarginalLikelihood(RepeatedData::group(x2, y2), gp::toTheta({}, true), true, 1e-10, nullptr,
                                         gp::Solver::Toeplitz),
               Error);
}

TEST(Reduction, PredictionEqualsConditioningOnEveryObservation) {
  Eigen::VectorXd x, y;
  repeatedData(4, 30, x, y);
  const gp::KernelParams p{0.3, 0.2, 1e-3};
  const GaussianProcess grouped = GaussianProcess::condition(RepeatedData::group(x, y), p, true, 1e-10);
  // Textbook posterior on all observations.
  const Eigen::Index n = x.size();
  Eigen::MatrixXd k(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j)
      k(i, j) = p.constant * std::exp(-0.5 * std::pow(x[i] - x[j], 2) / (p.length_scale * p.length_scale));
  Eigen::MatrixXd kn = k;
  kn.diagonal().array() += p.noise_level + 1e-10;
  const Eigen::LLT<Eigen::MatrixXd> llt(kn);
  Eigen::VectorXd xs = Eigen::VectorXd::LinSpaced(17, -0.1, 1.1), mean, sd;
  grouped.predict(xs, mean, &sd);
  for (Eigen::Index t = 0; t < xs.size(); ++t) {
    Eigen::VectorXd ks(n);
    for (Eigen::Index i = 0; i < n; ++i)
      ks[i] = p.constant * std::exp(-0.5 * std::pow(x[i] - xs[t], 2) / (p.length_scale * p.length_scale));
    const double m = ks.dot(llt.solve(y));
    const double v = p.constant + p.noise_level - ks.dot(llt.solve(ks));
    EXPECT_NEAR(mean[t], m, 1e-9);
    EXPECT_NEAR(sd[t], std::sqrt(v), 1e-7);
  }
}

TEST(Likelihood, GradientMatchesFiniteDifferences) {
  Eigen::VectorXd x, y;
  repeatedData(3, 25, x, y);
  const RepeatedData d = RepeatedData::group(x, y);
  const Eigen::VectorXd theta = gp::toTheta({0.4, 0.25, 3e-4}, true);
  Eigen::VectorXd g;
  gp::logMarginalLikelihood(d, theta, true, 1e-10, &g);
  for (Eigen::Index j = 0; j < theta.size(); ++j) {
    const double h = 1e-5;
    Eigen::VectorXd tp = theta, tm = theta;
    tp[j] += h;
    tm[j] -= h;
    const double fd =
        (gp::logMarginalLikelihood(d, tp, true, 1e-10) - gp::logMarginalLikelihood(d, tm, true, 1e-10)) / (2 * h);
    EXPECT_NEAR(g[j], fd, 1e-4 * (1 + std::abs(fd))) << "component " << j;
  }
}

TEST(Fit, IsDeterministicAndRespectsBounds) {
  Eigen::VectorXd x, y;
  repeatedData(5, 50, x, y);
  gp::GpOptions o;
  o.initial = {0.5, 0.3, 0.01};
  o.noise_bounds = {1e-2, 1.0};  // forces the noise onto its lower bound
  o.constant_bounds = {1e-4, 1e2};
  o.length_scale_bounds = {1e-2, 10};
  const GaussianProcess a = GaussianProcess::fit(x, y, o), b = GaussianProcess::fit(x, y, o);
  EXPECT_EQ(a.params().constant, b.params().constant);
  EXPECT_EQ(a.params().length_scale, b.params().length_scale);
  EXPECT_EQ(a.params().noise_level, b.params().noise_level);
  EXPECT_NEAR(a.params().noise_level, 1e-2, 1e-9);
  EXPECT_GT(a.evaluations(), 0);
}

TEST(Fit, RejectsInvalidOptions) {
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(5, 0, 1), y = x;
  gp::GpOptions o;
  o.initial.length_scale = 1e6;  // outside the default bounds
  EXPECT_THROW(GaussianProcess::fit(x, y, o), Error);
  o = {};
  o.noise_bounds = {0.0, 1.0};
  EXPECT_THROW(GaussianProcess::fit(x, y, o), Error);
  o = {};
  o.restarts = -1;
  EXPECT_THROW(GaussianProcess::fit(x, y, o), Error);
}

class SklearnParity : public ::testing::TestWithParam<const char*> {};

TEST_P(SklearnParity, OptimumAndPredictionsMatch) {
  const std::string path =
      (ddace::findRepository("", {"test/data/gp"}) / "test/data/gp" / (std::string("sklearn_") + GetParam() + ".json"))
          .string();
  const YAML::Node f = YAML::LoadFile(path);
  gp::GpOptions o;
  o.use_constant = f["use_constant"].as<bool>();
  o.alpha = f["alpha"].as<double>();
  o.initial = {f["initial"]["constant"].as<double>(), f["initial"]["length_scale"].as<double>(),
               f["initial"]["noise_level"].as<double>()};
  o.constant_bounds = bounds(f["constant_bounds"]);
  o.length_scale_bounds = bounds(f["length_scale_bounds"]);
  o.noise_bounds = bounds(f["noise_bounds"]);
  o.restarts = f["restarts"].as<int>();
  o.optimize = f["optimize"].as<bool>();
  const GaussianProcess model = GaussianProcess::fit(vec(f["x"]), vec(f["y"]), o);

  const double sk_lml = f["log_marginal_likelihood"].as<double>();
  // Equal, or better (a restart may find a higher optimum), within 1e-3 relative.
  EXPECT_GE(model.logMarginalLikelihood(), sk_lml - 1e-3 * std::abs(sk_lml));
  EXPECT_NEAR(model.logMarginalLikelihood(), sk_lml, 1e-3 * std::abs(sk_lml));

  Eigen::VectorXd mean, sd;
  model.predict(vec(f["x_test"]), mean, &sd);
  const Eigen::VectorXd sk_mean = vec(f["mean"]), sk_sd = vec(f["std"]);
  for (Eigen::Index i = 0; i < mean.size(); ++i) {
    EXPECT_NEAR(mean[i], sk_mean[i], 1e-4) << "mean at test input " << i;
    EXPECT_NEAR(sd[i], sk_sd[i], 1e-4) << "std at test input " << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Fixtures, SklearnParity, ::testing::Values("distinct", "no_constant", "repeated", "fixed"));
