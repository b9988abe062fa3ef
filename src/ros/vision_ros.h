// Conversions between the vision core and ROS messages, shared by tracker_node,
// recorder_node and synthetic_camera_node (library ddace_ros).
#pragma once

#include <string>
#include <vector>

#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>

#include "ddace/EntityArray.h"
#include "ddace/vision/synthetic_camera.h"
#include "ddace/vision/tracker.h"

namespace ddace::ros_vision {

/// Tracker states -> EntityArray in the `frame_id` frame at `stamp`.
ddace::EntityArray toMsg(const std::vector<vision::EntityState>& states, const ros::Time& stamp,
                         const std::string& frame_id);
/// EntityArray -> the poses the synthetic camera renders; visible = false draws a hand over it.
std::vector<vision::TrueEntity> trueEntities(const ddace::EntityArray& msg);
/// CameraInfo (K, D plumb_bob or rational_polynomial, image size) -> CameraModel;
/// invalid when K is all zero.
vision::CameraModel fromMsg(const sensor_msgs::CameraInfo& info);
/// CameraModel -> CameraInfo of a `width` x `height` image (no distortion when D is empty).
sensor_msgs::CameraInfo toMsg(const vision::CameraModel& camera, int width, int height, const std::string& frame_id);

}  // namespace ddace::ros_vision
