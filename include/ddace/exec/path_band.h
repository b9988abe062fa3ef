// The ±kσ band of a planned path, for display (rviz markers, plots).
//
// At every path point the band is offset by k·stddev along the path's left normal
// (direction of travel rotated by +90°), on both sides. Units: metres, table frame.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ddace/exec/path_follower.h"

namespace ddace::exec {

/// The band's two edges: [point] left (+k·σ) and right (−k·σ). Empty for a path of fewer
/// than two points. A missing stddev entry counts as 0.
void sigmaBandEdges(const PlannedPath& path, double k_sigma, std::vector<Eigen::Vector2d>& left,
                    std::vector<Eigen::Vector2d>& right);

/// The band as a triangle list (6 vertices per path interval), ready for a TRIANGLE_LIST marker.
std::vector<Eigen::Vector2d> sigmaBandTriangles(const PlannedPath& path, double k_sigma);

}  // namespace ddace::exec
