#include "vision_ros.h"

#include "ddace/common/error.h"

namespace ddace::ros_vision {

ddace::EntityArray toMsg(const std::vector<vision::EntityState>& states, const ros::Time& stamp,
                         const std::string& frame_id) {
  ddace::EntityArray msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = frame_id;
  for (const auto& s : states) {
    ddace::Entity e;
    e.name = s.name;
    e.kind = task::toString(s.kind);
    e.pose.x = s.pose.x;
    e.pose.y = s.pose.y;
    e.pose.theta = s.pose.yaw;
    e.visible = s.visible;
    e.stale = s.stale;
    if (s.last_seen > 0) e.last_seen = ros::Time(s.last_seen);
    msg.entities.push_back(e);
  }
  return msg;
}

std::vector<vision::TrueEntity> trueEntities(const ddace::EntityArray& msg) {
  std::vector<vision::TrueEntity> out;
  for (const auto& e : msg.entities) out.push_back({e.name, {e.pose.x, e.pose.y, e.pose.theta}, !e.visible});
  return out;
}

vision::CameraModel fromMsg(const sensor_msgs::CameraInfo& info) {
  vision::CameraModel m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m.K(r, c) = info.K[static_cast<size_t>(3 * r + c)];
  m.valid = info.K[0] > 0 && info.K[4] > 0;
  m.D.assign(info.D.begin(), info.D.end());
  if (info.width > 0 && info.height > 0)
    m.image_size = cv::Size(static_cast<int>(info.width), static_cast<int>(info.height));
  return m;
}

sensor_msgs::CameraInfo toMsg(const vision::CameraModel& camera, int width, int height, const std::string& frame_id) {
  sensor_msgs::CameraInfo info;
  info.header.frame_id = frame_id;
  info.width = static_cast<uint32_t>(width);
  info.height = static_cast<uint32_t>(height);
  info.distortion_model = camera.D.size() == 8 ? "rational_polynomial" : "plumb_bob";
  info.D = camera.D.empty() ? std::vector<double>(5, 0.0) : camera.D;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      info.K[static_cast<size_t>(3 * r + c)] = camera.K(r, c);
      info.P[static_cast<size_t>(4 * r + c)] = camera.K(r, c);
    }
  info.R[0] = info.R[4] = info.R[8] = 1.0;
  return info;
}

}  // namespace ddace::ros_vision
