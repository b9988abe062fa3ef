// The tf frame names every ddace node uses by default (each node's ~frame_id overrides
// its own). "table": origin at a table corner, x and y along its edges, z up, metres
// (REP-103); every position on a ddace topic is in it. "overhead_camera": the optical
// frame of the camera above the table (images, camera_info).
#pragma once

namespace ddace::nodes {

inline constexpr const char* kTableFrame = "table";
inline constexpr const char* kCameraFrame = "overhead_camera";

}  // namespace ddace::nodes
