// TrackerNode: see include/ddace/ros/tracker.h.
#include "ddace/ros/tracker.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <mutex>
#include <optional>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/TransformStamped.h>
#include <image_transport/image_transport.h>
#include <opencv2/videoio.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include "exec_conversions.h"
#include "params.h"
#include "vision_ros.h"
#include "ddace/EntityArray.h"
#include "ddace/common/error.h"
#include "ddace/vision/camera_calibration.h"
#include "ddace/vision/debug_image.h"
#include "ddace/vision/tracker.h"

namespace ddace::nodes {

class TrackerNode::Impl {
 public:
  Impl(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh), it_(nh), pit_(pnh), updater_(nh, pnh) {
    // Read in some input modes only, or by diagnostic_updater (~diagnostic_period).
    rosparam::alsoReads(
        pnh_, {"camera_matrix", "distortion", "video_width", "video_height", "video_rate_hz", "diagnostic_period"});
    const std::string markers = rosparam::requireString(pnh_, "markers_file", "path to config/markers.yaml");
    const std::string tuning = rosparam::param<std::string>(pnh_, "tracker_file", "");
    tracker_ = std::make_unique<vision::Tracker>(vision::loadTrackerConfig(markers, tuning));
    // With the task to run, a task entity without a marker is refused now, not waited for.
    if (const std::string task = rosparam::param<std::string>(pnh_, "task", ""); !task.empty())
      vision::requireTaskEntities(tracker_->config().markers, markers, ros_exec::loadTaskSpec(task), task);
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
                  " (the table's pose in the camera frame, with intrinsics) is required");
    // Intrinsics: a calibration file (camera_info YAML), or ~camera_matrix, or the
    // camera_info topic (in every input mode; the first two win over it).
    const std::string calibration = rosparam::param<std::string>(pnh_, "camera_calibration_file", "");
    if (!calibration.empty()) {
      const vision::CameraCalibration cal = vision::loadCameraCalibration(calibration);
      setCamera(cal.camera, "calibration file " + calibration);
    } else if (const auto K = rosparam::optionalParam<std::vector<double>>(pnh_, "camera_matrix")) {
      if (K->size() != 9) throw Error("parameter " + pnh_.resolveName("camera_matrix") + " needs 9 numbers");
      sensor_msgs::CameraInfo info;
      std::copy(K->begin(), K->end(), info.K.begin());
      info.D = rosparam::param(pnh_, "distortion", std::vector<double>{});
      const vision::CameraModel model = ros_vision::fromMsg(info);
      if (!model.valid)
        throw Error("parameter " + pnh_.resolveName("camera_matrix") + " is not a camera matrix (fx, fy must be > 0)");
      setCamera(model, "parameter " + pnh_.resolveName("camera_matrix"));
    }
    info_sub_ = nh_.subscribe("camera_info", 2, &Impl::onCameraInfo, this);
    updater_.setHardwareID("overhead camera");
    updater_.add("tracker", [this](diagnostic_updater::DiagnosticStatusWrapper& d) { diagnose(d); });
    diag_timer_ =
        nh_.createSteadyTimer(ros::WallDuration(0.5), [this](const ros::SteadyTimerEvent&) { updater_.update(); });

    entities_pub_ = nh_.advertise<ddace::EntityArray>("/ddace/entities", 10);
    markers_pub_ = pnh_.advertise<visualization_msgs::MarkerArray>("markers", 2);
    debug_pub_ = pit_.advertise("debug_image", 1);

    video_device_ = rosparam::param(pnh_, "video_device", defaults_.video_device);
    video_file_ = rosparam::param<std::string>(pnh_, "video_file", "");
    if (video_device_ < 0 && video_file_.empty()) {
      image_sub_ = it_.subscribe("image_raw", 2, &Impl::onImage, this);
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
    vision::VideoTimeline file_time;
    while (ros::ok() && !stop_) {
      if (!capture_.read(frame) || frame.empty()) {
        if (!video_file_.empty()) {
          ROS_INFO("tracker_node: end of %s", video_file_.c_str());
          break;
        }
        ROS_ERROR_THROTTLE(1.0, "tracker_node: no frame from /dev/video%d", video_device_);
      } else {
        ros::Time stamp = ros::Time::now();
        if (!video_file_.empty())
          stamp.fromSec(file_time.stamp(capture_.get(cv::CAP_PROP_POS_MSEC) / 1000.0, stamp.toSec()));
        if (raw_pub_.getNumSubscribers() > 0) {
          std_msgs::Header h;
          h.stamp = stamp;
          h.frame_id = kCameraFrame;
          raw_pub_.publish(cv_bridge::CvImage(h, frame.channels() == 1 ? "mono8" : "bgr8", frame).toImageMsg());
        }
        if (info_pub_.getNumSubscribers() > 0) publishCameraInfo(frame.size(), stamp);
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
                                       : "cannot open V4L2 device /dev/video" + std::to_string(video_device_) +
                                             " (another camera: video_device:=N; a recording: video_file:=FILE;"
                                             " no camera or robots: sim:=true rehearses on a simulated table)");
    const int width = rosparam::param(pnh_, "video_width", defaults_.video_width);
    const int height = rosparam::param(pnh_, "video_height", defaults_.video_height);
    if (width > 0) capture_.set(cv::CAP_PROP_FRAME_WIDTH, width);
    if (height > 0) capture_.set(cv::CAP_PROP_FRAME_HEIGHT, height);
    // The captured frames as a topic too, for rosbag and image viewers (only when watched),
    // with the intrinsics in use.
    raw_pub_ = it_.advertise("image_raw", 1);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("camera_info", 1);
    const double camera_fps = capture_.get(cv::CAP_PROP_FPS);
    capture_rate_hz_ = rosparam::param(pnh_, "video_rate_hz", camera_fps > 0 ? camera_fps : defaults_.video_rate_hz);
    if (!(capture_rate_hz_ > 0 && capture_rate_hz_ <= 1000))
      throw Error("parameter " + pnh_.resolveName("video_rate_hz") + " must be in (0, 1000] Hz");
  }

  /// Uses `model` from now on (called once: intrinsics do not change while running).
  void setCamera(const vision::CameraModel& model, const std::string& source) {
    std::lock_guard<std::mutex> lock(mutex_);
    tracker_->setCamera(model);
    if (!table_in_camera_.empty())
      tracker_->setFixedTableFrame(vision::TableFrame::fromCameraPose(
          model.K, table_in_camera_, "parameter " + pnh_.resolveName("table_in_camera")));
    camera_ = model;
    camera_source_ = source;
    have_camera_ = true;
    ROS_INFO("tracker_node: intrinsics from %s (undistortion, marker height correction)", source.c_str());
  }

  void onCameraInfo(const sensor_msgs::CameraInfoConstPtr& info) {
    if (have_camera_) return;  // given by a file or parameter, or already received
    try {
      vision::CameraModel model = ros_vision::fromMsg(*info);
      if (!model.valid) {
        ROS_ERROR_THROTTLE(5.0, "tracker_node: %s carries no camera matrix (K is zero); ignored",
                           info_sub_.getTopic().c_str());
        return;
      }
      setCamera(model, "topic " + info_sub_.getTopic());
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(5.0, "tracker_node: %s: %s", info_sub_.getTopic().c_str(), e.what());
    }
  }

  void publishCameraInfo(const cv::Size& size, const ros::Time& stamp) {
    if (!have_camera_) return;
    sensor_msgs::CameraInfo info = ros_vision::toMsg(camera_, size.width, size.height, "overhead_camera");
    info.header.stamp = stamp;
    info_pub_.publish(info);
  }

  void onImage(const sensor_msgs::ImageConstPtr& msg) {
    // A driver that publishes camera_info sends it along with the images: do not measure
    // without the intrinsics it brings (raised markers would be off by centimetres).
    if (!have_camera_ && cameraInfoAdvertised()) {
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

  /// Whether anyone publishes the camera_info topic. The subscriber's count is not enough:
  /// it counts connected publishers, and the image topic can connect first (then the first
  /// frames were measured without the intrinsics, off by millimetres to centimetres). The
  /// master knows every advertised topic; asked at most once a second.
  bool cameraInfoAdvertised() {
    if (info_sub_.getNumPublishers() > 0) return true;
    const ros::WallTime now = ros::WallTime::now();
    if (now < next_info_query_) return info_advertised_;
    next_info_query_ = now + ros::WallDuration(1.0);
    ros::master::V_TopicInfo topics;
    info_advertised_ = ros::master::getTopics(topics) &&
                       std::any_of(topics.begin(), topics.end(),
                                   [&](const ros::master::TopicInfo& t) { return t.name == info_sub_.getTopic(); });
    return info_advertised_;
  }

  void process(const cv::Mat& image, const ros::Time& stamp) {
    if (!table_in_camera_.empty() && !have_camera_) {
      ROS_WARN_THROTTLE(5.0,
                        "tracker_node: ~table_in_camera needs intrinsics (camera_info, "
                        "~camera_calibration_file or ~camera_matrix); waiting for them");
      return;
    }
    vision::FrameResult fr;
    std::optional<vision::ParallaxEstimate> parallax;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      try {
        fr = tracker_->process(image, stamp.toSec());
      } catch (const Error& e) {
        ROS_ERROR_THROTTLE(5.0, "tracker_node: %s", e.what());
        return;
      }
      if (fr.table_valid && fr.height_correction == vision::HeightCorrection::NoIntrinsics)
        parallax = tracker_->parallaxWithoutIntrinsics();
      last_ = fr;
      last_parallax_ = parallax;
    }
    if (!fr.table_valid)
      ROS_WARN_THROTTLE(5.0, "tracker_node: table frame unknown: %s",
                        fr.table_refused ? refusedText(fr).c_str() : "not all four corner markers are visible");
    else if (fr.table_refused)
      ROS_WARN_THROTTLE(5.0, "tracker_node: %s; keeping the previous table frame", refusedText(fr).c_str());
    if (fr.height_correction == vision::HeightCorrection::IntrinsicsDoNotFit)
      ROS_ERROR_THROTTLE(10.0,
                         "tracker_node: the intrinsics from %s do not fit the table frame (another camera, or "
                         "another resolution?): raised markers are NOT corrected for parallax",
                         camera_source_.c_str());
    if (parallax && !warned_no_intrinsics_) {
      // Once, with the number: what running without intrinsics costs on this table.
      warned_no_intrinsics_ = true;
      ROS_WARN(
          "tracker_node: no intrinsics (no camera_info, ~camera_calibration_file or ~camera_matrix): markers "
          "%.1f cm above the table are off by up to %.0f mm at the far corners (camera about %.2f m above the "
          "table%s); give a camera calibration to correct it",
          maxMarkerHeight() * 100, parallax->max_error_m * 1000, parallax->camera_height_m,
          parallax->focal_assumed ? ", focal length assumed" : "");
    }
    entities_pub_.publish(ros_vision::toMsg(fr.entities, stamp, frame_id_));
    if (publish_tf_) publishTf(fr, stamp);
    if (markers_pub_.getNumSubscribers() > 0) publishMarkers(fr, stamp);
    if (debug_pub_.getNumSubscribers() > 0) publishDebug(image, fr, stamp);
  }

  std::string refusedText(const vision::FrameResult& fr) const {
    return vision::tableRefusedText(fr, tracker_->config().table.max_reprojection_px);
  }

  double maxMarkerHeight() const {
    double h = 0;
    for (const auto& e : tracker_->config().markers.entities) h = std::max(h, e.height_m);
    return h;
  }

  /// One status "tracker" (the rule: vision::trackerStatus).
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& d) {
    std::lock_guard<std::mutex> lock(mutex_);
    const vision::TrackerStatus status =
        vision::trackerStatus(last_, last_parallax_, tracker_->config().table.max_reprojection_px);
    using Level = vision::TrackerStatus::Level;
    d.summary(status.level == Level::Ok     ? diagnostic_msgs::DiagnosticStatus::OK
              : status.level == Level::Warn ? diagnostic_msgs::DiagnosticStatus::WARN
                                            : diagnostic_msgs::DiagnosticStatus::ERROR,
              status.summary);
    if (!last_) return;
    const vision::FrameResult& fr = *last_;
    d.add("table frame", fr.table_valid ? "valid" : "unknown");
    d.add("table reprojection error (px)", fr.table_reprojection_px);
    d.add("table fit refused", fr.table_refused);
    d.add("height correction", vision::heightCorrectionName(fr.height_correction));
    d.add("intrinsics", have_camera_ ? camera_source_ : "none");
    if (last_parallax_) d.add("expected error without intrinsics (mm)", last_parallax_->max_error_m * 1000);
    d.add("entities visible", status.visible);
    d.add("entities stale", status.stale);
    d.add("search", fr.full_frame ? std::string("full frame") : std::to_string(fr.rois.size()) + " regions");
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
      m.type =
          e.kind == task::EntityKind::Goal ? visualization_msgs::Marker::CYLINDER : visualization_msgs::Marker::ARROW;
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
    const cv::Mat out = vision::drawDebugImage(image, fr, tracker_->config().markers);
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
  ros::Publisher entities_pub_, markers_pub_, info_pub_;
  tf2_ros::TransformBroadcaster tf_;
  diagnostic_updater::Updater updater_;
  ros::SteadyTimer diag_timer_;
  std::mutex mutex_;  // the tracker: frames (capture thread) vs camera_info and diagnostics (spinner)
  std::unique_ptr<vision::Tracker> tracker_;
  vision::CameraModel camera_;
  std::string camera_source_;
  std::optional<vision::FrameResult> last_;
  std::optional<vision::ParallaxEstimate> last_parallax_;
  bool warned_no_intrinsics_ = false;
  bool info_advertised_ = false;   // cameraInfoAdvertised()'s last answer from the master ...
  ros::WallTime next_info_query_;  // ... and when to ask again
  std::string frame_id_, video_file_;
  int video_device_ = -1;
  bool publish_tf_ = true;
  std::atomic<bool> have_camera_{false};
  std::vector<double> table_in_camera_;
  cv::VideoCapture capture_;
  double capture_rate_hz_ = 30.0;
  std::atomic<bool> stop_{false};
};

TrackerNode::TrackerNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

TrackerNode::~TrackerNode() = default;

bool TrackerNode::capturing() const {
  return impl_->capturing();
}

void TrackerNode::run() {
  impl_->run();
}

void TrackerNode::stop() {
  impl_->stop();
}

}  // namespace ddace::nodes
