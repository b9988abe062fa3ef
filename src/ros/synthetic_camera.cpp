// SyntheticCameraNode: see include/ddace/ros/synthetic_camera.h.
#include "ddace/ros/synthetic_camera.h"

#include <map>
#include <memory>

#include <cv_bridge/cv_bridge.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>

#include "exec_conversions.h"
#include "params.h"
#include "vision_ros.h"
#include "ddace/EntityArray.h"
#include "ddace/common/error.h"
#include "ddace/vision/synthetic_camera.h"

namespace ddace::nodes {

class SyntheticCameraNode::Impl {
 public:
  Impl(ros::NodeHandle nh, ros::NodeHandle pnh) : it_(nh) {
    const std::string markers = rosparam::requireString(pnh, "markers_file", "path to config/markers.yaml");
    const std::string camera = rosparam::requireString(pnh, "camera_file", "path to the synthetic camera's YAML");
    // The camera frames the table the markers file's corners span (the task's table).
    const vision::MarkerConfig marker_config = vision::loadMarkerConfig(markers);
    camera_ = std::make_unique<vision::SyntheticCamera>(
        vision::framedOnCorners(vision::loadSyntheticCameraConfig(camera), marker_config), marker_config);
    const SyntheticCameraNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    // Bodies as the task states them; without a task, the default footprint of each kind.
    const std::string task = rosparam::param<std::string>(pnh, "task", "");
    if (!task.empty()) {
      const task::TaskSpec spec = ros_exec::loadTaskSpec(task);
      for (int i = 0; i < static_cast<int>(spec.entities.size()); ++i)
        footprints_[spec.entities[static_cast<size_t>(i)].name] = spec.footprint(i);
    }
    const double rate_hz = rosparam::param(pnh, "rate_hz", defaults.rate_hz);
    if (!(rate_hz > 0 && rate_hz <= 1000))
      throw Error("parameter " + pnh.resolveName("rate_hz") + " must be in (0, 1000]");
    info_ = ros_vision::toMsg(camera_->camera(), camera_->config().width, camera_->config().height, frame_id_);
    pub_ = it_.advertiseCamera("image_raw", 2);
    sub_ = nh.subscribe("true_entities", 10, &Impl::onTruth, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz), &Impl::onTimer, this);
    const auto& c = camera_->config();
    ROS_INFO("synthetic_camera_node: %dx%d at %.1f Hz from %s; a table of %.2f x %.2f m seen from %.2f m above",
             c.width, c.height, rate_hz, sub_.getTopic().c_str(), c.table_size.width, c.table_size.height,
             c.position[2]);
  }

 private:
  void onTruth(const ddace::EntityArray::ConstPtr& msg) {
    if (first_.isZero()) first_ = msg->header.stamp;
    truth_ = msg;
  }

  void onTimer(const ros::TimerEvent&) {
    if (!truth_ || truth_->header.stamp <= last_) return;
    if (pub_.getNumSubscribers() == 0) return;  // nobody looks: render nothing
    last_ = truth_->header.stamp;
    std::vector<vision::TrueEntity> truth = ros_vision::trueEntities(*truth_);
    for (auto& te : truth)
      if (const auto it = footprints_.find(te.name); it != footprints_.end()) te.footprint = it->second;
    const cv::Mat img = camera_->render(truth, (last_ - first_).toSec());
    std_msgs::Header h;
    h.stamp = last_;
    h.frame_id = frame_id_;
    // By pointer: in a nodelet manager the tracker receives these very messages.
    const auto info = boost::make_shared<sensor_msgs::CameraInfo>(info_);
    info->header = h;
    pub_.publish(cv_bridge::CvImage(h, "mono8", img).toImageMsg(), info);
  }

  image_transport::ImageTransport it_;
  image_transport::CameraPublisher pub_;
  ros::Subscriber sub_;
  ros::Timer timer_;
  std::unique_ptr<vision::SyntheticCamera> camera_;
  sensor_msgs::CameraInfo info_;
  std::string frame_id_;
  std::map<std::string, task::Footprint> footprints_;  // by entity name, from ~task
  ddace::EntityArray::ConstPtr truth_;
  ros::Time first_, last_;
};

SyntheticCameraNode::SyntheticCameraNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : impl_(std::make_unique<Impl>(nh, pnh)) {}

SyntheticCameraNode::~SyntheticCameraNode() = default;

}  // namespace ddace::nodes
