// Gaussian-process regression on one scalar input with the kernel
//
//     k(x, x') = C * exp(-(x - x')^2 / (2 l^2)) + sigma_n^2 * [same observation]
//
// (scikit-learn's `ConstantKernel(C) * RBF(l) + WhiteKernel(sigma_n^2)`; with
// `use_constant = false` the factor C is fixed to 1, i.e. `RBF(l) + WhiteKernel`),
// a zero prior mean (scikit-learn's `normalize_y=False`) and `alpha` added to the
// diagonal of the training covariance (scikit-learn's `alpha`, default 1e-10).
//
// Hyper-parameters are optimised in log space, theta = [log C, log l, log sigma_n^2]
// (without log C when the constant is off) -- the same vector, order and bounds
// semantics as scikit-learn -- by maximising the log marginal likelihood with its
// analytic gradient and LBFGS++'s bounded L-BFGS-B solver. Restarts start from
// points drawn uniformly in the log-bounds by a fixed-seed generator: a fit is a
// pure function of its data and options.
//
// Repeated inputs. Training data are kept as *distinct* inputs x_i, the number of
// observations m_i at each, their mean ybar_i and the within-input residual sum of
// squares RSS = sum_ij (y_ij - ybar_i)^2. With s^2 = sigma_n^2 + alpha,
// A = K + s^2 diag(1/m), N = sum m_i observations and n distinct inputs,
//
//   log p(y) = -1/2 ybar' A^-1 ybar - 1/2 log|A| - 1/2 sum log m_i
//              - (N - n)/2 log s^2 - RSS / (2 s^2) - N/2 log(2 pi),
//
// exactly the likelihood of all N observations; posterior mean and variance also
// only need A. A fit therefore costs O(n^3) however many observations repeat.
//
// Owns: the regression maths. Must not: know about paths, frames or files.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace ddace::gp {

/// Closed interval for one hyper-parameter, in natural (not log) units.
struct Bounds {
  double lower = 1e-5;
  double upper = 1e5;
};

/// Kernel hyper-parameters in natural units.
struct KernelParams {
  double constant = 1.0;      ///< C, signal variance (units of y squared); 1 when the constant is off
  double length_scale = 1.0;  ///< l, units of x
  double noise_level = 1.0;   ///< sigma_n^2, white-noise variance (units of y squared)
};

struct GpOptions {
  bool use_constant = true;    ///< C * RBF + White when true, RBF + White when false
  double alpha = 1e-10;        ///< added to the diagonal of the training covariance (jitter)
  KernelParams initial;        ///< first start of the optimiser (scikit-learn: the kernel's values)
  Bounds constant_bounds;      ///< bounds of C
  Bounds length_scale_bounds;  ///< bounds of l
  Bounds noise_bounds;         ///< bounds of sigma_n^2
  int restarts = 2;            ///< extra optimiser starts after `initial` (scikit-learn's n_restarts_optimizer)
  uint64_t seed = 0;           ///< seed of the restart points (SplitMix64)
  bool optimize = true;        ///< false: keep `initial` (scikit-learn's optimizer=None)
  int max_iterations = 200;    ///< per optimiser start
};

/// Training data grouped by distinct input (see the header comment).
struct RepeatedData {
  Eigen::VectorXd inputs;  ///< distinct x_i, ascending
  Eigen::VectorXd counts;  ///< m_i >= 1
  Eigen::VectorXd means;   ///< ybar_i
  double residual_ss = 0;  ///< sum over all observations of (y_ij - ybar_i)^2
  double total = 0;        ///< N = sum m_i

  /// Groups observations whose inputs are exactly equal. Throws ddace::Error when the
  /// sizes differ, there is no observation or a value is not finite.
  static RepeatedData group(const Eigen::VectorXd& x, const Eigen::VectorXd& y);
};

/// How logMarginalLikelihood factorises A. Auto: Toeplitz when the distinct inputs are
/// equally spaced and all counts are equal (then A is symmetric Toeplitz: Durbin's
/// algorithm for the log-determinant, Trench's for the inverse, O(n^2) instead of O(n^3);
/// a primitive's data always has this structure, while the condition number of A is
/// provably below 1e11), Cholesky otherwise or when Durbin's recursion loses positive
/// definiteness numerically.
enum class Solver { Auto, Cholesky, Toeplitz };

/// True when `data` has the structure the Toeplitz solver needs.
bool isToeplitz(const RepeatedData& data);

/// log theta vector of `p` (size 3 with the constant, 2 without).
Eigen::VectorXd toTheta(const KernelParams& p, bool use_constant);
KernelParams fromTheta(const Eigen::VectorXd& theta, bool use_constant);

/// Log marginal likelihood of the grouped data at log hyper-parameters `theta` and,
/// when `gradient` is not null, its gradient with respect to theta. Returns -inf when
/// the covariance is not numerically positive definite.
double logMarginalLikelihood(const RepeatedData& data, const Eigen::VectorXd& theta, bool use_constant, double alpha,
                             Eigen::VectorXd* gradient = nullptr, Solver solver = Solver::Auto);

/// The same quantity computed the textbook way on all N observations (an N x N
/// Cholesky). O(N^3): for tests of the reduction and for small data only.
double logMarginalLikelihoodNaive(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& theta,
                                  bool use_constant, double alpha, Eigen::VectorXd* gradient = nullptr);

class GaussianProcess {
 public:
  GaussianProcess() = default;

  /// Fits hyper-parameters (unless options.optimize is false) and conditions on the data.
  /// Throws ddace::Error for empty data or invalid options (bounds, initial values).
  static GaussianProcess fit(const RepeatedData& data, const GpOptions& options = {});
  static GaussianProcess fit(const Eigen::VectorXd& x, const Eigen::VectorXd& y, const GpOptions& options = {});
  /// Conditions on the data with fixed hyper-parameters (no optimisation), e.g. after loading.
  /// Throws ddace::Error when the covariance is not positive definite.
  static GaussianProcess condition(const RepeatedData& data, const KernelParams& params, bool use_constant,
                                   double alpha);

  /// Posterior mean at `x`; `stddev` (optional) receives the standard deviation of a new
  /// observation there, white noise included (scikit-learn's predict(return_std=True)).
  void predict(const Eigen::VectorXd& x, Eigen::VectorXd& mean, Eigen::VectorXd* stddev = nullptr) const;

  const KernelParams& params() const { return params_; }
  bool usesConstant() const { return use_constant_; }
  double alpha() const { return alpha_; }
  const RepeatedData& data() const { return data_; }
  /// Log marginal likelihood at the fitted hyper-parameters.
  double logMarginalLikelihood() const { return lml_; }
  /// Objective evaluations spent by the optimiser (0 without optimisation).
  int evaluations() const { return evaluations_; }

 private:
  void conditionOnData();

  RepeatedData data_;
  KernelParams params_;
  bool use_constant_ = true;
  double alpha_ = 1e-10;
  double lml_ = 0;
  int evaluations_ = 0;
  /// Of A = K + s^2 diag(1/m). Computed on an empty matrix until fit: Eigen's default LLT
  /// leaves its status unset, and moving an unfitted process (a Primitive being filled in)
  /// read it (UBSan: not a valid value for type 'ComputationInfo').
  Eigen::LLT<Eigen::MatrixXd> llt_{Eigen::MatrixXd()};
  Eigen::VectorXd weights_;  ///< A^-1 ybar
};

}  // namespace ddace::gp
