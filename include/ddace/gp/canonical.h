// The canonical frame of a motion and resampling by progress (DDACE, Sec. IV-C).
//
// The canonical frame of a motion from `start` to `end` puts the start at the origin,
// the start->end direction along +x and the start-end distance at 1: a point p of the
// table frame maps to  c = R(-phi) (p - start) / d,  with d = |end - start| and
// phi = atan2 of end - start; the inverse  p = start + d R(phi) c  is the retargeting
// of the paper. Canonical coordinates are dimensionless (fractions of d).
//
// Progress is the fraction of arc length travelled, in [0, 1]. Resampling by progress
// gives points equally spaced along the path, so two paths of the same shape compare
// equal however fast they were traversed.
//
// Owns: these transforms (used by gp primitives and eval's Fréchet distance).
#pragma once

#include <vector>

#include <Eigen/Core>

namespace ddace::gp {

/// Motions shorter than this (metres) have no canonical frame.
inline constexpr double kMinMotionLength = 1e-6;

class CanonicalFrame {
 public:
  /// The frame of a motion from `start` to `end` (table frame, metres). Throws
  /// ddace::Error when they are closer than kMinMotionLength.
  CanonicalFrame(const Eigen::Vector2d& start, const Eigen::Vector2d& end);

  /// Table frame (metres) -> canonical (dimensionless).
  Eigen::Vector2d toCanonical(const Eigen::Vector2d& p) const;
  /// Canonical -> table frame (metres): the retargeting of a canonical path.
  Eigen::Vector2d fromCanonical(const Eigen::Vector2d& c) const;
  std::vector<Eigen::Vector2d> toCanonical(const std::vector<Eigen::Vector2d>& path) const;
  std::vector<Eigen::Vector2d> fromCanonical(const std::vector<Eigen::Vector2d>& path) const;

  const Eigen::Vector2d& origin() const { return origin_; }
  double scale() const { return scale_; }  ///< d, metres per canonical unit
  double angle() const { return angle_; }  ///< phi, radians

 private:
  Eigen::Vector2d origin_;
  double scale_ = 1;
  double angle_ = 0;
  Eigen::Matrix2d rotation_;  ///< R(phi)
};

/// Arc-length fraction of every point of `path`: 0 at the first, 1 at the last
/// (all 0 for a path that does not move).
std::vector<double> progress(const std::vector<Eigen::Vector2d>& path);

/// `n` points equally spaced in progress along `path` (linear interpolation between
/// samples; the first and last points are kept exactly). A path that does not move
/// yields n copies of its point. Throws ddace::Error for an empty path or n < 2.
std::vector<Eigen::Vector2d> resampleByProgress(const std::vector<Eigen::Vector2d>& path, int n);

}  // namespace ddace::gp
