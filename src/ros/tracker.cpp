// TrackerNode: see include/ddace/ros/tracker.h.
#include "ddace/ros/tracker.h"

#include <atomic>
#include <cmath>
#include <memory>

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <image_transport/image_transport.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include "params.h"
#include "vision_ros.h"
#include "ddace/EntityArray.h"
#include "ddace/common/error.h"
#include "ddace/vision/tracker.h"

namespace ddace::nodes {

class TrackerNode::Impl {
 public:
  Impl(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh), it_(nh), pit_(pnh) {
    const std::string markers = rosparam::requireString(pnh_, "markers_file", "path to config/markers.yaml");
    const std::string tuning = rosparam::param<std::string>(pnh_, "tracker_file", "");
    tracker_ = std::make_unique<vision::Tracker>(vision::loadTrackerConfig(markers, tuning));
    frame_id_ = rosparam::param(pnh_, "frame_id", defaults_.frame_id);
    publish_tf_ = rosparam::param(pnh_, "publish_tf", defaults_.publish_tf);

    // A calibrated camera instead of corner markers: the table frame's pose in the
    // camera's optical frame, [x y z roll pitch yaw] (metres, radians).
    if (const auto t = rosparam::optionalParam<std::vector<double>>(pnh_, "table_in_camera")) {
      table_in_camera_ = *t;
      if (table_in_camera_.size() != 6)
        throw Error("parameter " + pnh_.resolveName("table_in_camera") + " needs 6 numbers [x y z roll pitch yaw]");
    }
    if (tracker_->config().markers.corners.empty() && table_in_camera_.empty())
      throw Error(markers + ": no corner markers, so parameter " + pnh_.resolveName("table_in_camera") +
                  " (the table's pose in the camera frame, with camera_info) is required");
    if (const auto K = rosparam::optionalParam<std::vector<double>>(pnh_, "camera_matrix")) {
      if (K->size() != 9) throw Error("parameter " + pnh_.resolveName("camera_matrix") + " needs 9 numbers");
      sensor_msgs::CameraInfo info;
      std::copy(K->begin(), K->end(), info.K.begin());
      info.D = rosparam::param(pnh_, "distortion", std::vector<double>{});
      setCamera(info);
    }

    entities_pub_ = nh_.advertise<ddace::EntityArray>("/ddace/entities", 10);
    markers_pub_ = pnh_.advertise<visualization_msgs::MarkerArray>("markers", 2);
    debug_pub_ = pit_.advertise("debug_image", 1);

    video_device_ = rosparam::param(pnh_, "video_device", defaults_.video_device);
    video_file_ = rosparam::param<std::string>(pnh_, "video_file", "");
    if (video_device_ < 0 && video_file_.empty()) {
      image_sub_ = it_.subscribe("image_raw", 2, &Impl::onImage, this);
      info_sub_ = nh_.subscribe("camera_info", 2, &Impl::onCameraInfo, this);
      ROS_INFO("tracker_node: %s, waiting for %s", markers.c_str(), image_sub_.getTopic().c_str());
    } else {
      openCapture();
    }
  }

  bool capturing() const { return capture_.isOpened(); }

  /// The capture loop (device or file); without one, waits for shutdown.
  void run() {
    if (!capturing()) {
      ros::waitForShutdown();
      return;
    }
    ros::Rate rate(capture_rate_hz_);
    cv::Mat frame;
    while (ros::ok() && !stop_) {
      if (!capture_.read(frame) || frame.empty()) {
        if (!video_file_.empty()) {
          ROS_INFO("tracker_node: end of %s", video_file_.c_str());
          break;
        }
        ROS_ERROR_THROTTLE(1.0, "tracker_node: no frame from /dev/video%d", video_device_);
      } else {
        const ros::Time stamp = ros::Time::now();
        if (raw_pub_.getNumSubscribers() > 0) {
          std_msgs::Header h;
          h.stamp = stamp;
          h.frame_id = kCameraFrame;
          raw_pub_.publish(cv_bridge::CvImage(h, frame.channels() == 1 ? "mono8" : "bgr8", frame).toImageMsg());
        }
        process(frame, stamp);
      }
      if (!video_file_.empty()) rate.sleep();
    }
  }

  void stop() { stop_ = true; }

 private:
  /// Opens ~video_file or ~video_device now, so a missing device is refused at start.
  void openCapture() {
    if (!video_file_.empty() ? !capture_.open(video_file_) : !capture_.open(video_device_, cv::CAP_V4L2))
      throw Error(!video_file_.empty() ? "cannot open video file " + video_file_
                                       : "cannot open V4L2 device /dev/video" + std::to_string(video_device_));
    const int width = rosparam::param(pnh_, "video_width", defaults_.video_width);
    const int height = rosparam::param(pnh_, "video_height", defaults_.video_height);
    if (width > 0) capture_.set(cv::CAP_PROP_FRAME_WIDTH, width);
    if (height > 0) capture_.set(cv::CAP_PROP_FRAME_HEIGHT, height);
    // The captured frames as a topic too, for rosbag and image viewers (only when watched).
    raw_pub_ = it_.advertise("image_raw", 1);
    const double camera_fps = capture_.get(cv::CAP_PROP_FPS);
    capture_rate_hz_ = rosparam::param(pnh_, "video_rate_hz", camera_fps > 0 ? camera_fps : 30.0);
    if (!(capture_rate_hz_ > 0 && capture_rate_hz_ <= 1000))
      throw Error("parameter " + pnh_.resolveName("video_rate_hz") + " must be in (0, 1000] Hz");
  }

  void setCamera(const sensor_msgs::CameraInfo& info) {
    const vision::CameraModel model = ros_vision::fromMsg(info);
    if (!model.valid) return;
    tracker_->setCamera(model);
    if (!table_in_camera_.empty()) {
      const double r = table_in_camera_[3], p = table_in_camera_[4], y = table_in_camera_[5];
      const cv::Matx33d Rx(1, 0, 0, 0, std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r));
      const cv::Matx33d Ry(std::cos(p), 0, std::sin(p), 0, 1, 0, -std::sin(p), 0, std::cos(p));
      const cv::Matx33d Rz(std::cos(y), -std::sin(y), 0, std::sin(y), std::cos(y), 0, 0, 0, 1);
      tracker_->setFixedTableFrame(vision::TableFrame::fromCameraPose(
          model.K, Rz * Ry * Rx, cv::Vec3d(table_in_camera_[0], table_in_camera_[1], table_in_camera_[2])));
    }
    have_camera_ = true;
  }

  void onCameraInfo(const sensor_msgs::CameraInfoConstPtr& info) {
    if (have_camera_) return;  // intrinsics do not change while running
    try {
      setCamera(*info);
      if (have_camera_) ROS_INFO("tracker_node: using camera_info intrinsics (undistortion, marker height correction)");
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(5.0, "tracker_node: camera_info: %s", e.what());
    }
  }

  void onImage(const sensor_msgs::ImageConstPtr& msg) {
    // A driver that publishes camera_info sends it along with the images: do not measure
    // without the intrinsics it brings (raised markers would be off by centimetres).
    if (!have_camera_ && info_sub_.getNumPublishers() > 0) {
      ROS_INFO_THROTTLE(2.0, "tracker_node: waiting for %s", info_sub_.getTopic().c_str());
      return;
    }
    cv_bridge::CvImageConstPtr img;
    try {
      const bool mono = msg->encoding == "mono8" || msg->encoding == "8UC1";
      img = cv_bridge::toCvShare(msg, mono ? "mono8" : "bgr8");
    } catch (const cv_bridge::Exception& e) {
      ROS_ERROR_THROTTLE(5.0, "tracker_node: image on %s: %s", image_sub_.getTopic().c_str(), e.what());
      return;
    }
    process(img->image, msg->header.stamp.isZero() ? ros::Time::now() : msg->header.stamp);
  }

  void process(const cv::Mat& image, const ros::Time& stamp) {
    if (!table_in_camera_.empty() && !have_camera_) {
      ROS_WARN_THROTTLE(5.0, "tracker_node: ~table_in_camera needs camera_info; waiting for it");
      return;
    }
    vision::FrameResult fr;
    try {
      fr = tracker_->process(image, stamp.toSec());
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(5.0, "tracker_node: %s", e.what());
      return;
    }
    if (!fr.table_valid)
      ROS_WARN_THROTTLE(5.0, "tracker_node: table frame unknown: not all four corner markers are visible");
    entities_pub_.publish(ros_vision::toMsg(fr.entities, stamp, frame_id_));
    if (publish_tf_) publishTf(fr, stamp);
    if (markers_pub_.getNumSubscribers() > 0) publishMarkers(fr, stamp);
    if (debug_pub_.getNumSubscribers() > 0) publishDebug(image, fr, stamp);
  }

  void publishTf(const vision::FrameResult& fr, const ros::Time& stamp) {
    std::vector<geometry_msgs::TransformStamped> tfs;
    for (const auto& e : fr.entities) {
      if (e.stale) continue;
      geometry_msgs::TransformStamped t;
      t.header.stamp = stamp;
      t.header.frame_id = frame_id_;
      t.child_frame_id = e.name;
      t.transform.translation.x = e.pose.x;
      t.transform.translation.y = e.pose.y;
      t.transform.rotation.z = std::sin(e.pose.yaw / 2);
      t.transform.rotation.w = std::cos(e.pose.yaw / 2);
      tfs.push_back(t);
    }
    if (!tfs.empty()) tf_.sendTransform(tfs);
  }

  void publishMarkers(const vision::FrameResult& fr, const ros::Time& stamp) {
    visualization_msgs::MarkerArray arr;
    int id = 0;
    for (const auto& e : fr.entities) {
      visualization_msgs::Marker m;
      m.header.frame_id = frame_id_;
      m.header.stamp = stamp;
      m.ns = "entities";
      m.id = id++;
      m.type = e.kind == task::EntityKind::Goal ? visualization_msgs::Marker::CYLINDER : visualization_msgs::Marker::ARROW;
      m.action = e.stale ? visualization_msgs::Marker::DELETE : visualization_msgs::Marker::ADD;
      m.pose.position.x = e.pose.x;
      m.pose.position.y = e.pose.y;
      m.pose.orientation.z = std::sin(e.pose.yaw / 2);
      m.pose.orientation.w = std::cos(e.pose.yaw / 2);
      m.scale.x = e.kind == task::EntityKind::Goal ? 0.04 : 0.05;
      m.scale.y = e.kind == task::EntityKind::Goal ? 0.04 : 0.015;
      m.scale.z = e.kind == task::EntityKind::Goal ? 0.005 : 0.015;
      m.color.a = 1.0;
      m.color.g = e.visible ? 0.8f : 0.6f;  // green when seen, orange while held
      m.color.r = e.visible ? 0.1f : 1.0f;
      arr.markers.push_back(m);
      visualization_msgs::Marker t = m;
      t.ns = "names";
      t.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
      t.text = e.name + (e.visible ? "" : " (held)");
      t.pose.position.z = 0.05;
      t.pose.orientation = geometry_msgs::Quaternion();
      t.pose.orientation.w = 1.0;
      t.scale.z = 0.03;
      t.color.r = t.color.g = t.color.b = 1.0f;
      arr.markers.push_back(t);
    }
    markers_pub_.publish(arr);
  }

  void publishDebug(const cv::Mat& image, const vision::FrameResult& fr, const ros::Time& stamp) {
    cv::Mat out;
    if (image.channels() == 1)
      cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
    else
      out = image.clone();
    for (const auto& r : fr.rois) cv::rectangle(out, r, cv::Scalar(255, 160, 0), 1);
    const auto& markers = tracker_->config().markers;
    for (const auto& d : fr.detections) {
      std::vector<cv::Point> poly;
      for (const auto& c : d.corners) poly.emplace_back(cvRound(c.x), cvRound(c.y));
      const bool corner = markers.isCorner(d.id);
      cv::polylines(out, poly, true, corner ? cv::Scalar(255, 0, 255) : cv::Scalar(0, 220, 0), 2);
      cv::circle(out, poly[0], 3, cv::Scalar(0, 0, 255), cv::FILLED);  // printed top-left
      const vision::EntityMarker* em = markers.entityById(d.id);
      const std::string label = em ? em->name : "corner " + std::to_string(d.id);
      cv::putText(out, label, poly[0] + cv::Point(0, -6), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 255), 1);
    }
    std::string status = fr.full_frame ? "full frame" : std::to_string(fr.rois.size()) + " regions";
    if (!fr.table_valid) status += ", NO TABLE FRAME";
    for (const auto& e : fr.entities)
      if (e.stale) status += ", " + e.name + " stale";
    cv::putText(out, status, cv::Point(10, 25), cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 255), 2);
    std_msgs::Header h;
    h.stamp = stamp;
    h.frame_id = kCameraFrame;
    debug_pub_.publish(cv_bridge::CvImage(h, "bgr8", out).toImageMsg());
  }

  const TrackerNode::Params defaults_;
  ros::NodeHandle nh_, pnh_;
  image_transport::ImageTransport it_, pit_;
  image_transport::Subscriber image_sub_;
  image_transport::Publisher debug_pub_, raw_pub_;
  ros::Subscriber info_sub_;
  ros::Publisher entities_pub_, markers_pub_;
  tf2_ros::TransformBroadcaster tf_;
  std::unique_ptr<vision::Tracker> tracker_;
  std::string frame_id_, video_file_;
  int video_device_ = -1;
  bool publish_tf_ = true, have_camera_ = false;
  std::vector<double> table_in_camera_;
  cv::VideoCapture capture_;
  double capture_rate_hz_ = 30.0;
  std::atomic<bool> stop_{false};
};

TrackerNode::TrackerNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

TrackerNode::~TrackerNode() = default;

bool TrackerNode::capturing() const { return impl_->capturing(); }

void TrackerNode::run() { impl_->run(); }

void TrackerNode::stop() { impl_->stop(); }

}  // namespace ddace::nodes
