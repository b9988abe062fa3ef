// synthetic_camera_node (test helper): renders the true entity poses into overhead
// camera images so the real tracker can run in tests and simulations.
//
// In:  `true_entities` (ddace/EntityArray; e.g. mock_robot_node's output remapped to
//      /ddace/true_entities, or a test's scripted poses).
// Out: `image_raw` (mono8) + `camera_info` (image_transport camera publisher).
// Each frame shows the latest truth and carries its stamp, so the tracker's output
// can be compared with the truth at exactly that time; a frame is rendered only when a
// newer truth arrived (the camera never publishes two frames with one stamp).
// An entity whose truth says visible = false gets a hand drawn over it (tests script
// occlusions this way, to the frame); occlusion times in the camera file count from the
// first truth message.
#include <iostream>
#include <memory>

#include <cv_bridge/cv_bridge.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>

#include "../ros/params.h"
#include "../ros/vision_ros.h"
#include "ddace/EntityArray.h"
#include "ddace/common/error.h"
#include "ddace/vision/synthetic_camera.h"

namespace {

using namespace ddace;

class SyntheticCameraNode {
 public:
  SyntheticCameraNode(ros::NodeHandle nh, ros::NodeHandle pnh) : it_(nh) {
    const std::string markers = rosparam::requireString(pnh, "markers_file", "path to config/markers.yaml");
    const std::string camera = rosparam::requireString(pnh, "camera_file", "path to the synthetic camera's YAML");
    camera_ = std::make_unique<vision::SyntheticCamera>(vision::loadSyntheticCameraConfig(camera),
                                                        vision::loadMarkerConfig(markers));
    frame_id_ = rosparam::param<std::string>(pnh, "frame_id", "overhead_camera");
    const double rate_hz = rosparam::param(pnh, "rate_hz", 30.0);
    if (!(rate_hz > 0 && rate_hz <= 1000))
      throw Error("parameter " + pnh.resolveName("rate_hz") + " must be in (0, 1000]");
    info_ = ros_vision::toMsg(camera_->camera(), camera_->config().width, camera_->config().height, frame_id_);
    pub_ = it_.advertiseCamera("image_raw", 2);
    sub_ = nh.subscribe("true_entities", 10, &SyntheticCameraNode::onTruth, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz), &SyntheticCameraNode::onTimer, this);
    ROS_INFO("synthetic_camera_node: %dx%d at %.1f Hz from %s", camera_->config().width, camera_->config().height,
             rate_hz, sub_.getTopic().c_str());
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
    const cv::Mat img = camera_->render(ros_vision::trueEntities(*truth_), (last_ - first_).toSec());
    std_msgs::Header h;
    h.stamp = last_;
    h.frame_id = frame_id_;
    sensor_msgs::CameraInfo info = info_;
    info.header = h;
    pub_.publish(*cv_bridge::CvImage(h, "mono8", img).toImageMsg(), info);
  }

  image_transport::ImageTransport it_;
  image_transport::CameraPublisher pub_;
  ros::Subscriber sub_;
  ros::Timer timer_;
  std::unique_ptr<vision::SyntheticCamera> camera_;
  sensor_msgs::CameraInfo info_;
  std::string frame_id_;
  ddace::EntityArray::ConstPtr truth_;
  ros::Time first_, last_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "synthetic_camera_node");
  try {
    SyntheticCameraNode node(ros::NodeHandle(), ros::NodeHandle("~"));
    ros::spin();
  } catch (const ddace::Error& e) {
    // On stderr as well: rosconsole may not be up when the configuration is refused.
    std::cerr << "synthetic_camera_node: " << e.what() << std::endl;
    return 1;
  }
  return 0;
}
