// RecorderNode: see include/ddace/ros/recorder.h.
#include "ddace/ros/recorder.h"

#include <memory>
#include <optional>
#include <sstream>

#include <ros/ros.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include "params.h"
#include "vision_ros.h"
#include "ddace/EntityArray.h"
#include "ddace/Label.h"
#include "ddace/common/error.h"
#include "ddace/vision/recorder.h"

namespace ddace::nodes {

class RecorderNode::Impl {
 public:
  Impl(ros::NodeHandle nh, ros::NodeHandle pnh) {
    const std::string markers = rosparam::requireString(pnh, "markers_file", "path to config/markers.yaml");
    const std::string file = rosparam::requireString(pnh, "recorder_file", "path to config/recorder.yaml");
    config_ = vision::loadRecorderConfig(file, vision::loadMarkerConfig(markers));
    const std::string dir = rosparam::param<std::string>(pnh, "output_dir", "");
    if (!dir.empty()) config_.output_dir = dir;
    recorder_ = std::make_unique<vision::DemoRecorder>(config_.spec, config_.output_dir, config_.flush_period_s);
    // Without labels from the keyboard, they are inferred from the motion when a
    // demonstration is stopped (docs/labels.md); the example names the actions.
    std::optional<label::Example> example;
    if (!config_.example.empty())
      example =
          label::Example::fromDemonstration(task::readDemonstrationCsv(config_.example, config_.spec), config_.spec);
    recorder_->inferLabels(config_.infer_labels, std::move(example));
    positions_ = std::make_unique<vision::LatestPositions>(config_.spec);

    state_pub_ = pnh.advertise<std_msgs::String>("state", 1, true);
    entities_sub_ = nh.subscribe("/ddace/entities", 10, &Impl::onEntities, this);
    labels_sub_ = nh.subscribe("/ddace/labels", 100, &Impl::onLabel, this);
    start_srv_ = pnh.advertiseService("start", &Impl::onStart, this);
    stop_srv_ = pnh.advertiseService("stop", &Impl::onStop, this);
    discard_srv_ = pnh.advertiseService("discard", &Impl::onDiscard, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / config_.rate_hz), &Impl::onTimer, this);
    setState("ready: " + config_.output_dir + " (call ~start)");
  }

 private:
  void setState(const std::string& s) {
    std_msgs::String msg;
    msg.data = s;
    state_pub_.publish(msg);
    ROS_INFO("recorder_node: %s", s.c_str());
  }

  void onEntities(const ddace::EntityArray::ConstPtr& msg) {
    latest_ = msg;
    for (const auto& e : msg->entities) {
      const bool measured = !(e.stale && !e.visible && e.last_seen.isZero());
      positions_->update(e.name, Eigen::Vector2d(e.pose.x, e.pose.y), e.stale, measured, msg->header.stamp.toSec());
    }
  }

  void onLabel(const ddace::Label::ConstPtr& msg) {
    if (!recorder_->recording()) {
      ROS_WARN("recorder_node: label %s %s %s ignored: not recording", msg->entity.c_str(), msg->action.c_str(),
               msg->target.c_str());
      return;
    }
    try {
      recorder_->setLabel(msg->entity, msg->action, msg->target);
      ROS_INFO("recorder_node: %s -> %s %s", msg->entity.c_str(), msg->action.empty() ? "idle" : msg->action.c_str(),
               msg->target.c_str());
    } catch (const Error& e) {
      ROS_ERROR("recorder_node: label refused: %s", e.what());
      setState("label refused: " + std::string(e.what()));
    }
  }

  void onTimer(const ros::TimerEvent&) {
    if (!recorder_->recording() || !latest_ || latest_->header.stamp <= last_row_) return;
    const auto p = positions_->all();
    if (!p) return;
    try {
      if (recorder_->addRow(latest_->header.stamp.toSec(), *p)) {
        last_row_ = latest_->header.stamp;
        positions_->countRow();
      }
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(1.0, "recorder_node: %s", e.what());
    }
  }

  /// Why the scene at `t` is no start for a demonstration, "" when it is at rest. The first
  /// row is every entity's start: a robot still being placed would start the demonstration
  /// with a motion (and a goal moving then reads as a moved goal).
  std::string notAtRest(double t) const {
    const std::string moving = positions_->moving(t), appeared = positions_->appeared(t);
    if (moving.empty() && appeared.empty()) return "";
    std::ostringstream os;
    os << "not started:";
    if (!moving.empty())
      os << " " << moving << " moved within the last " << positions_->stillSeconds()
         << " s; a demonstration starts from a scene at rest: let go of everything, then start again";
    if (!appeared.empty())
      os << (moving.empty() ? "" : ";") << " " << appeared << " seen for less than " << positions_->stillSeconds()
         << " s (the tracker has just begun to see " << (appeared.find(',') == std::string::npos ? "it" : "them")
         << "), not yet known to be at rest: start again in a moment, nothing to do";
    return os.str();
  }

  bool onStart(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    const auto p = positions_->all();
    if (recorder_->recording()) {
      res.message = "already recording " + path_ + " (stop or discard it first)";
    } else if (!latest_) {
      res.message = "no /ddace/entities received yet (is the tracker running?)";
    } else if (!p) {
      res.message = "not every entity has been seen yet: " + positions_->missing() + " (are their markers visible?)";
    } else if (const std::string why = notAtRest(latest_->header.stamp.toSec()); !why.empty()) {
      res.message = why;
    } else {
      try {
        t0_ = latest_->header.stamp;
        path_ = recorder_->start(t0_.toSec());
        recorder_->addRow(t0_.toSec(), *p);
        last_row_ = t0_;
        positions_->resetRows();
        positions_->countRow();
        res.success = true;
        res.message = "recording " + path_;
      } catch (const Error& e) {
        res.message = e.what();
      }
    }
    setState(res.message);
    return true;
  }

  bool onStop(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    if (!recorder_->recording()) {
      res.message = "not recording";
    } else {
      const size_t rows = recorder_->rows();
      const double duration = recorder_->duration();
      try {
        const std::string path = recorder_->stop();
        std::ostringstream os;
        os.precision(9);
        os << "saved " << path << ": " << rows << " rows, " << duration << " s, start stamp " << std::fixed
           << t0_.toSec();
        if (const std::string hidden = positions_->staleRowsReport(); !hidden.empty()) os << "; " << hidden;
        if (!recorder_->inferredSteps().empty()) os << "; labels inferred: " << recorder_->inferredSteps();
        const auto& notes = recorder_->inferenceNotes();
        if (!notes.empty()) os << "; " << notes.size() << " to check:";
        for (const auto& n : notes) {
          os << "\n  " << n;
          ROS_WARN("recorder_node: check %s", n.c_str());
        }
        if (const std::string& advice = recorder_->inferenceAdvice(); !advice.empty()) {
          std::istringstream lines(advice);
          for (std::string line; std::getline(lines, line);) os << "\n  " << line;
          ROS_WARN("recorder_node: %s", advice.c_str());
        }
        res.message = os.str();
        res.success = true;
      } catch (const Error& e) {
        res.message = std::string("not saved: ") + e.what();
      }
    }
    setState(res.message);
    return true;
  }

  bool onDiscard(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    if (!recorder_->recording()) {
      res.message = "not recording";
    } else {
      recorder_->discard();
      res.success = true;
      res.message = "discarded " + path_;
    }
    setState(res.message);
    return true;
  }

  vision::RecorderConfig config_;
  std::unique_ptr<vision::DemoRecorder> recorder_;
  ros::Publisher state_pub_;
  ros::Subscriber entities_sub_, labels_sub_;
  ros::ServiceServer start_srv_, stop_srv_, discard_srv_;
  ros::Timer timer_;
  ddace::EntityArray::ConstPtr latest_;
  std::unique_ptr<vision::LatestPositions> positions_;
  ros::Time t0_, last_row_;
  std::string path_;
};

RecorderNode::RecorderNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

RecorderNode::~RecorderNode() = default;

}  // namespace ddace::nodes
