// Discrete Fréchet distance (Eiter & Mannila, 1994) and the spec's normalised form.
//
// Units: frechetDistance is in the units of its inputs (metres for table-frame
// paths); normalisedFrechet is dimensionless (fractions of the ground-truth
// segment's start-end distance), see docs/task-format.md, "FD".
#pragma once

#include <vector>

#include <Eigen/Core>

namespace ddace::eval {

/// Discrete Fréchet distance between polylines p and q (lengths may differ):
/// O(|p| |q|) time, O(min(|p|, |q|)) memory. Throws ddace::Error when one is empty.
double frechetDistance(const std::vector<Eigen::Vector2d>& p, const std::vector<Eigen::Vector2d>& q);

/// Number of points both paths are resampled to by normalisedFrechet.
inline constexpr int kFrechetPoints = 100;

/// The spec's FD of one token: both paths resampled to 100 points by progress and
/// expressed in the canonical frame of `ground_truth` (its first and last points),
/// then frechetDistance. Throws ddace::Error when a path is empty or the ground
/// truth's start and end coincide.
double normalisedFrechet(const std::vector<Eigen::Vector2d>& generated,
                         const std::vector<Eigen::Vector2d>& ground_truth);

}  // namespace ddace::eval
