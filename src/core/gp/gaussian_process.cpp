#include "ddace/gp/gaussian_process.h"

#include <LBFGSB.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "ddace/common/error.h"
#include "ddace/common/random.h"

namespace ddace::gp {

namespace {

constexpr double kToeplitzMaxCondition = 1e11;
constexpr double kLog2Pi = 1.8378770664093454835606594728112;

/// Squared distances between all pairs of `a` and `b`.
Eigen::MatrixXd squaredDistances(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  Eigen::MatrixXd d(a.size(), b.size());
  for (Eigen::Index j = 0; j < b.size(); ++j)
    for (Eigen::Index i = 0; i < a.size(); ++i) {
      const double diff = a[i] - b[j];
      d(i, j) = diff * diff;
    }
  return d;
}

void checkBounds(const Bounds& b, double initial, const char* name) {
  if (!(b.lower > 0) || !(b.upper >= b.lower) || !std::isfinite(b.upper))
    throw Error(std::string("GP option ") + name + ": bounds must satisfy 0 < lower <= upper < inf");
  if (!(initial >= b.lower && initial <= b.upper))
    throw Error(std::string("GP option ") + name + ": initial value " + std::to_string(initial) +
                " lies outside its bounds");
}

/// -LML and its gradient for LBFGS++, remembering the best point seen (a line search
/// that gives up must not lose the progress made).
struct Objective {
  Objective(const RepeatedData& d, bool c, double a) : data(d), use_constant(c), alpha(a) {}
  const RepeatedData& data;
  bool use_constant;
  double alpha;
  int evaluations = 0;
  double best_f = std::numeric_limits<double>::infinity();
  Eigen::VectorXd best_theta;

  double operator()(const Eigen::VectorXd& theta, Eigen::VectorXd& grad) {
    ++evaluations;
    const double lml = logMarginalLikelihood(data, theta, use_constant, alpha, &grad);
    if (!std::isfinite(lml)) {
      // Not positive definite here: a huge value pushes the line search back.
      grad.setZero();
      return 1e100;
    }
    grad = -grad;
    if (-lml < best_f) {
      best_f = -lml;
      best_theta = theta;
    }
    return -lml;
  }
};

}  // namespace

RepeatedData RepeatedData::group(const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
  if (x.size() != y.size())
    throw Error("GP data: " + std::to_string(x.size()) + " inputs but " + std::to_string(y.size()) + " targets");
  if (x.size() == 0) throw Error("GP data: no observations");
  if (!x.allFinite() || !y.allFinite()) throw Error("GP data: an input or target is not a finite number");
  std::map<double, std::vector<double>> by_input;
  for (Eigen::Index i = 0; i < x.size(); ++i) by_input[x[i]].push_back(y[i]);
  RepeatedData d;
  const Eigen::Index n = static_cast<Eigen::Index>(by_input.size());
  d.inputs.resize(n);
  d.counts.resize(n);
  d.means.resize(n);
  Eigen::Index i = 0;
  for (const auto& [input, ys] : by_input) {
    double sum = 0;
    for (double v : ys) sum += v;
    const double mean = sum / ys.size();
    for (double v : ys) d.residual_ss += (v - mean) * (v - mean);
    d.inputs[i] = input;
    d.counts[i] = static_cast<double>(ys.size());
    d.means[i] = mean;
    ++i;
  }
  d.total = static_cast<double>(x.size());
  return d;
}

Eigen::VectorXd toTheta(const KernelParams& p, bool use_constant) {
  if (use_constant) return Eigen::Vector3d(std::log(p.constant), std::log(p.length_scale), std::log(p.noise_level));
  return Eigen::Vector2d(std::log(p.length_scale), std::log(p.noise_level));
}

KernelParams fromTheta(const Eigen::VectorXd& theta, bool use_constant) {
  KernelParams p;
  const int o = use_constant ? 1 : 0;
  p.constant = use_constant ? std::exp(theta[0]) : 1.0;
  p.length_scale = std::exp(theta[o]);
  p.noise_level = std::exp(theta[o + 1]);
  return p;
}

bool isToeplitz(const RepeatedData& data) {
  const Eigen::Index n = data.inputs.size();
  if (n < 2) return false;
  if ((data.counts.array() != data.counts[0]).any()) return false;
  const double h = (data.inputs[n - 1] - data.inputs[0]) / static_cast<double>(n - 1);
  if (!(h > 0)) return false;
  for (Eigen::Index i = 0; i < n; ++i)
    if (std::abs(data.inputs[i] - (data.inputs[0] + static_cast<double>(i) * h)) >
        1e-12 * (1 + std::abs(data.inputs[i])))
      return false;
  return true;
}

namespace {

/// The Toeplitz path of logMarginalLikelihood. Returns false when Durbin's recursion
/// meets a non-positive prediction-error variance (then the caller uses Cholesky).
bool toeplitzLml(const RepeatedData& data, const KernelParams& p, bool use_constant, double alpha, double& lml,
                 Eigen::VectorXd* gradient) {
  const Eigen::Index n = data.inputs.size();
  const double h = (data.inputs[n - 1] - data.inputs[0]) / static_cast<double>(n - 1);
  const double m = data.counts[0];
  const double s2 = p.noise_level + alpha;
  // First column of K (kernel) and of A = K + s2/m I.
  Eigen::VectorXd kcol(n), d2(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    d2[k] = (static_cast<double>(k) * h) * (static_cast<double>(k) * h);
    kcol[k] = p.constant * std::exp(-0.5 * d2[k] / (p.length_scale * p.length_scale));
  }
  const double a0 = kcol[0] + s2 / m;
  const Eigen::VectorXd rho = kcol / a0;  // rho[0] unused (the normalised diagonal is 1)

  // Durbin: y solves T_{n-1} y = -rho[1..n-1]; log det T_n from the prediction errors.
  // rho is read backwards; a reversed copy makes that a forward (vectorised) dot product.
  const Eigen::VectorXd rr = rho.reverse();  // rr[t] = rho[n-1-t]
  Eigen::VectorXd y(std::max<Eigen::Index>(n - 1, 1));
  double log_det_t = 0;
  double beta = 1, a = -rho[1];
  y[0] = -rho[1];
  for (Eigen::Index k = 1; k < n - 1; ++k) {
    beta *= (1 - a * a);
    if (!(beta > 0)) return false;
    log_det_t += std::log(beta);
    a = -(rho[k + 1] + rr.segment(n - 1 - k, k).dot(y.head(k))) / beta;
    for (Eigen::Index i = 0, j = k - 1; i <= j; ++i, --j) {  // y[0..k) += a * reversed y, in place
      const double yi = y[i], yj = y[j];
      y[i] = yi + a * yj;
      if (i != j) y[j] = yj + a * yi;
    }
    y[k] = a;
  }
  beta *= (1 - a * a);
  if (!(beta > 0)) return false;
  log_det_t += std::log(beta);
  const double gamma = 1.0 / beta;

  // Trench: the upper triangle of T^-1 column by column, from the recurrence
  // B(i, j) = B(i-1, j-1) + gamma (y[i-1] y[j-1] - y[n-1-i] y[n-1-j]).
  const Eigen::VectorXd yrev = y.head(n - 1).reverse();  // yrev[t] = y[n-2-t]
  Eigen::MatrixXd bm(n, n);
  bm(0, 0) = gamma;
  for (Eigen::Index j = 1; j < n; ++j) {
    bm(0, j) = gamma * y[j - 1];
    bm.col(j).segment(1, j) =
        bm.col(j - 1).head(j) + (gamma * y[j - 1]) * y.head(j) - (gamma * y[n - 1 - j]) * yrev.head(j);
  }
  // w = A^-1 ybar, and the sums of A^-1 along its diagonals (all the gradient needs).
  const Eigen::VectorXd w = (bm.selfadjointView<Eigen::Upper>() * data.means) / a0;
  Eigen::VectorXd diag_sum = Eigen::VectorXd::Zero(n);
  for (Eigen::Index j = 0; j < n; ++j) diag_sum.head(j + 1).reverse() += bm.col(j).head(j + 1);
  diag_sum /= a0;

  const double log_det_a = static_cast<double>(n) * std::log(a0) + log_det_t;
  lml = -0.5 * data.means.dot(w) - 0.5 * log_det_a - 0.5 * static_cast<double>(n) * std::log(m) -
        0.5 * (data.total - n) * std::log(s2) - 0.5 * data.residual_ss / s2 - 0.5 * data.total * kLog2Pi;
  if (!std::isfinite(lml)) return false;
  if (gradient) {
    // u[k] = sum over entries (i, j) with |i - j| = k of (w w' - A^-1)_ij; every dA/dtheta
    // is Toeplitz, so tr((w w' - A^-1) dA) = sum_k t_k u[k].
    Eigen::VectorXd u(n);
    for (Eigen::Index k = 0; k < n; ++k) {
      const double corr = w.head(n - k).dot(w.tail(n - k));
      u[k] = (k == 0 ? 1.0 : 2.0) * (corr - diag_sum[k]);
    }
    const double trace_k = kcol.dot(u);
    const double trace_l = kcol.cwiseProduct(d2).dot(u) / (p.length_scale * p.length_scale);
    const double g_noise = 0.5 * p.noise_level * u[0] / m +
                           p.noise_level * (-0.5 * (data.total - n) / s2 + 0.5 * data.residual_ss / (s2 * s2));
    gradient->resize(use_constant ? 3 : 2);
    if (use_constant) {
      (*gradient) << 0.5 * trace_k, 0.5 * trace_l, g_noise;
    } else {
      (*gradient) << 0.5 * trace_l, g_noise;
    }
  }
  return true;
}

}  // namespace

double logMarginalLikelihood(const RepeatedData& data, const Eigen::VectorXd& theta, bool use_constant, double alpha,
                             Eigen::VectorXd* gradient, Solver solver) {
  const KernelParams p = fromTheta(theta, use_constant);
  if (solver != Solver::Cholesky) {
    const bool structured = isToeplitz(data);
    if (solver == Solver::Toeplitz && !structured)
      throw Error("GP: the Toeplitz solver needs equally spaced inputs with equal counts");
    // Durbin's recursion loses accuracy faster than Cholesky as A becomes ill-conditioned
    // (about 1e-7 relative in the likelihood at a condition number of 1e10; plenty for the
    // optimiser, and the reported likelihood always comes from Cholesky). Auto keeps it to
    // covariances whose condition number is provably below 1e11 (lambda_max <= n a0 by
    // Gershgorin, lambda_min >= s^2/m).
    bool use = structured;
    if (use && solver == Solver::Auto) {
      const double s2m = (p.noise_level + alpha) / data.counts[0];
      use = static_cast<double>(data.inputs.size()) * (p.constant + s2m) / s2m <= kToeplitzMaxCondition;
    }
    double lml = 0;
    if (use && toeplitzLml(data, p, use_constant, alpha, lml, gradient)) return lml;
    if (solver == Solver::Toeplitz) return -std::numeric_limits<double>::infinity();
  }
  const Eigen::Index n = data.inputs.size();
  const double s2 = p.noise_level + alpha;
  const Eigen::MatrixXd d2 = squaredDistances(data.inputs, data.inputs);
  const Eigen::MatrixXd k = p.constant * (-0.5 / (p.length_scale * p.length_scale) * d2).array().exp().matrix();
  Eigen::MatrixXd a = k;
  a.diagonal().array() += s2 / data.counts.array();
  const Eigen::LLT<Eigen::MatrixXd> llt(a);
  if (llt.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
  const Eigen::VectorXd w = llt.solve(data.means);
  const double log_det_a = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  const double lml = -0.5 * data.means.dot(w) - 0.5 * log_det_a - 0.5 * data.counts.array().log().sum() -
                     0.5 * (data.total - n) * std::log(s2) - 0.5 * data.residual_ss / s2 - 0.5 * data.total * kLog2Pi;
  if (gradient) {
    // dLML/dtheta_j = 1/2 tr((w w' - A^-1) dA/dtheta_j) plus, for the noise, the
    // derivative of the closed-form terms.
    Eigen::MatrixXd wm = -llt.solve(Eigen::MatrixXd::Identity(n, n));
    wm.noalias() += w * w.transpose();
    const double trace_k = (wm.array() * k.array()).sum();
    const double trace_l = (wm.array() * k.array() * d2.array()).sum() / (p.length_scale * p.length_scale);
    const double trace_n = (wm.diagonal().array() / data.counts.array()).sum();
    const double g_noise = 0.5 * p.noise_level * trace_n +
                           p.noise_level * (-0.5 * (data.total - n) / s2 + 0.5 * data.residual_ss / (s2 * s2));
    gradient->resize(theta.size());
    if (use_constant) {
      (*gradient) << 0.5 * trace_k, 0.5 * trace_l, g_noise;
    } else {
      (*gradient) << 0.5 * trace_l, g_noise;
    }
  }
  return lml;
}

double logMarginalLikelihoodNaive(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& theta,
                                  bool use_constant, double alpha, Eigen::VectorXd* gradient) {
  const KernelParams p = fromTheta(theta, use_constant);
  const Eigen::Index n = x.size();
  const Eigen::MatrixXd d2 = squaredDistances(x, x);
  const Eigen::MatrixXd rbf = p.constant * (-0.5 / (p.length_scale * p.length_scale) * d2).array().exp().matrix();
  Eigen::MatrixXd k = rbf;
  k.diagonal().array() += p.noise_level + alpha;
  const Eigen::LLT<Eigen::MatrixXd> llt(k);
  if (llt.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
  const Eigen::VectorXd w = llt.solve(y);
  const double lml =
      -0.5 * y.dot(w) - llt.matrixLLT().diagonal().array().log().sum() - 0.5 * static_cast<double>(n) * kLog2Pi;
  if (gradient) {
    Eigen::MatrixXd wm = w * w.transpose() - llt.solve(Eigen::MatrixXd::Identity(n, n));
    std::vector<Eigen::MatrixXd> dk;
    if (use_constant) dk.push_back(rbf);
    dk.push_back(rbf.cwiseProduct(d2) / (p.length_scale * p.length_scale));
    dk.push_back(p.noise_level * Eigen::MatrixXd::Identity(n, n));
    gradient->resize(theta.size());
    for (size_t j = 0; j < dk.size(); ++j) (*gradient)[j] = 0.5 * (wm.array() * dk[j].array()).sum();
  }
  return lml;
}

GaussianProcess GaussianProcess::fit(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const GpOptions& options) {
  return fit(RepeatedData::group(x, y), options);
}

GaussianProcess GaussianProcess::fit(const RepeatedData& data, const GpOptions& options) {
  if (data.inputs.size() == 0) throw Error("GP data: no observations");
  if (!(options.alpha >= 0) || !std::isfinite(options.alpha)) throw Error("GP option alpha must be >= 0");
  if (options.restarts < 0) throw Error("GP option restarts must be >= 0");
  if (options.use_constant) checkBounds(options.constant_bounds, options.initial.constant, "constant");
  checkBounds(options.length_scale_bounds, options.initial.length_scale, "length_scale");
  checkBounds(options.noise_bounds, options.initial.noise_level, "noise_level");

  GaussianProcess gp;
  gp.data_ = data;
  gp.use_constant_ = options.use_constant;
  gp.alpha_ = options.alpha;
  gp.params_ = options.initial;
  if (!options.use_constant) gp.params_.constant = 1.0;

  if (options.optimize) {
    std::vector<Bounds> bounds;
    if (options.use_constant) bounds.push_back(options.constant_bounds);
    bounds.push_back(options.length_scale_bounds);
    bounds.push_back(options.noise_bounds);
    const Eigen::Index dim = static_cast<Eigen::Index>(bounds.size());
    Eigen::VectorXd lb(dim), ub(dim);
    for (Eigen::Index j = 0; j < dim; ++j) {
      lb[j] = std::log(bounds[j].lower);
      ub[j] = std::log(bounds[j].upper);
    }
    LBFGSpp::LBFGSBParam<double> param;
    param.max_iterations = options.max_iterations;
    param.epsilon = 1e-5;  // projected gradient, like SciPy's pgtol
    param.epsilon_rel = 0;
    param.past = 1;
    param.delta = 1e-10;  // relative decrease of -LML between iterations (SciPy's default: 2.2e-9)
    param.max_linesearch = 40;
    LBFGSpp::LBFGSBSolver<double> solver(param);
    Objective objective(data, options.use_constant, options.alpha);

    SplitMix64 rng(options.seed);
    for (int start = 0; start <= options.restarts; ++start) {
      Eigen::VectorXd theta = start == 0 ? toTheta(gp.params_, options.use_constant) : Eigen::VectorXd(dim);
      if (start > 0)
        for (Eigen::Index j = 0; j < dim; ++j) theta[j] = lb[j] + (ub[j] - lb[j]) * rng.uniform();
      double fx = 0;
      try {
        solver.minimize(objective, theta, fx, lb, ub);
      } catch (const std::exception&) {
        // The line search gave up (flat or noisy objective): the best point seen counts.
      }
    }
    gp.evaluations_ = objective.evaluations;
    if (objective.best_theta.size() == 0)
      throw Error("GP fit: the covariance is not positive definite at any tried hyper-parameters");
    gp.params_ = fromTheta(objective.best_theta, options.use_constant);
  }
  gp.conditionOnData();
  return gp;
}

GaussianProcess GaussianProcess::condition(const RepeatedData& data, const KernelParams& params, bool use_constant,
                                           double alpha) {
  if (data.inputs.size() == 0) throw Error("GP data: no observations");
  GaussianProcess gp;
  gp.data_ = data;
  gp.params_ = params;
  gp.use_constant_ = use_constant;
  gp.alpha_ = alpha;
  gp.conditionOnData();
  return gp;
}

void GaussianProcess::conditionOnData() {
  if (!use_constant_) params_.constant = 1.0;
  const Eigen::Index n = data_.inputs.size();
  const double inv2l2 = 0.5 / (params_.length_scale * params_.length_scale);
  Eigen::MatrixXd a(n, n);
  if (isToeplitz(data_)) {
    // Equally spaced inputs: n kernel values instead of n^2 exponentials.
    const double h = (data_.inputs[n - 1] - data_.inputs[0]) / static_cast<double>(n - 1);
    Eigen::VectorXd col(n);
    for (Eigen::Index k = 0; k < n; ++k) col[k] = params_.constant * std::exp(-inv2l2 * std::pow(k * h, 2));
    for (Eigen::Index j = 0; j < n; ++j)
      for (Eigen::Index i = 0; i < n; ++i) a(i, j) = col[std::abs(i - j)];
  } else {
    a = params_.constant * (-inv2l2 * squaredDistances(data_.inputs, data_.inputs)).array().exp().matrix();
  }
  a.diagonal().array() += (params_.noise_level + alpha_) / data_.counts.array();
  llt_.compute(a);
  if (llt_.info() != Eigen::Success)
    throw Error("GP: the training covariance is not positive definite (noise level too small?)");
  weights_ = llt_.solve(data_.means);
  // The reported (and stored) likelihood comes from this backward-stable factorisation.
  const double s2 = params_.noise_level + alpha_;
  lml_ = -0.5 * data_.means.dot(weights_) - llt_.matrixLLT().diagonal().array().log().sum() -
         0.5 * data_.counts.array().log().sum() - 0.5 * (data_.total - static_cast<double>(n)) * std::log(s2) -
         0.5 * data_.residual_ss / s2 - 0.5 * data_.total * kLog2Pi;
}

void GaussianProcess::predict(const Eigen::VectorXd& x, Eigen::VectorXd& mean, Eigen::VectorXd* stddev) const {
  if (weights_.size() == 0) throw Error("GP: predict() before fit()");
  const Eigen::MatrixXd ks =
      params_.constant *
      (-0.5 / (params_.length_scale * params_.length_scale) * squaredDistances(data_.inputs, x)).array().exp().matrix();
  mean.noalias() = ks.transpose() * weights_;
  if (stddev) {
    const Eigen::MatrixXd v = llt_.matrixL().solve(ks);
    const Eigen::ArrayXd var = (params_.constant + params_.noise_level) - v.colwise().squaredNorm().transpose().array();
    *stddev = var.max(0.0).sqrt().matrix();
  }
}

}  // namespace ddace::gp
