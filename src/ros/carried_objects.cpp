// CarriedObjectsNode: see include/ddace/ros/carried_objects.h.
#include "ddace/ros/carried_objects.h"

#include <filesystem>
#include <map>
#include <optional>

#include <ros/ros.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>

#include "exec_conversions.h"
#include "params.h"
#include "ddace/task/task_dir.h"

namespace ddace::nodes {

namespace {

/// The task spec; with a task directory holding demos/, refused when a demonstration moves
/// an object no robot carries.
task::TaskSpec loadChecked(const std::string& task_path, const std::string& param) {
  ros_exec::requireAbsolute(task_path, param);
  namespace fs = std::filesystem;
  if (!fs::is_directory(fs::path(task_path) / "demos")) {
    ROS_INFO("carried_objects: %s has no demos/: objects are checked as their segments come", task_path.c_str());
    return ros_exec::loadTaskSpec(task_path);
  }
  const task::TaskDir dir = task::loadTaskDir(task_path);
  if (const auto refusal = exec::uncarriedObjectMotion(dir)) throw Error(task_path + ": " + *refusal);
  return dir.spec;
}

}  // namespace

class CarriedObjectsNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = loadChecked(task_path, pnh.resolveName("task"));
    const Params defaults;
    exec::CarriedObjectParams p;
    p.arrival_radius_m = spec_.arrival_radius;
    p.settle_s = rosparam::param(pnh, "settle_s", defaults.settle_s);
    p.pairing_s = rosparam::param(pnh, "pairing_s", defaults.pairing_s);
    const double rate_hz = rosparam::param(pnh, "rate_hz", defaults.rate_hz);
    if (!(rate_hz > 0)) throw Error("parameter '" + pnh.resolveName("rate_hz") + "' must be > 0");
    try {
      judge_ = std::make_unique<exec::CarriedObjects>(spec_, p);
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + " (parameters under '" + pnh.getNamespace() + "')");
    }
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto& e = spec_.entities[i];
      const int k = static_cast<int>(i);
      const std::string base = "/robots/" + e.name;
      if (e.kind == task::EntityKind::Robot) {
        subs_.push_back(nh.subscribe<ddace::Segment>(
            base + "/segment", 10, [this, k](const ddace::Segment::ConstPtr& m) { onRobotSegment(k, *m); }));
        subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
            base + "/segment_status", 20,
            [this, k](const ddace::SegmentStatus::ConstPtr& m) { onRobotStatus(k, *m); }));
      } else if (e.kind == task::EntityKind::Object) {
        status_pubs_[k] = nh.advertise<ddace::SegmentStatus>(base + "/segment_status", 10);
        subs_.push_back(nh.subscribe<ddace::Segment>(
            base + "/segment", 10, [this, k](const ddace::Segment::ConstPtr& m) { onObjectSegment(k, *m); }));
      }
    }
    const std::string topic = rosparam::param(pnh, "entities_topic", defaults.entities_topic);
    entities_sub_ = nh.subscribe(topic, 5, &Impl::onEntities, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz),
                            [this](const ros::TimerEvent&) { publish(judge_->update(now())); });
    ROS_INFO("carried_objects: task '%s': object segments judged from %s and their carriers' segments",
             spec_.name.c_str(), topic.c_str());
  }

 private:
  static double now() { return ros::Time::now().toSec(); }

  std::optional<task::Token> token(const ddace::Segment& m) const { return ros_exec::tokenOrNothing(m.token, spec_); }

  void onRobotSegment(int r, const ddace::Segment& m) {
    if (m.mode != ddace::Segment::MODE_FOLLOW) return;
    if (const auto t = token(m)) judge_->onRobotSegment(r, m.segment_id, m.step, *t);
  }

  void onRobotStatus(int r, const ddace::SegmentStatus& m) {
    if (const auto s = ros_exec::endedState(m.status)) publish(judge_->onRobotStatus(r, m.segment_id, *s, now()));
  }

  void onObjectSegment(int o, const ddace::Segment& m) {
    if (m.mode == ddace::Segment::MODE_STOP) return publish(judge_->stopObject(o));
    const auto t = token(m);
    if (!t) {
      exec::ObjectStatus s;
      s.entity = o, s.segment_id = m.segment_id, s.state = exec::SegmentState::Failed;
      s.message = "segment " + std::to_string(m.segment_id) + " for " + spec_.entities[o].name + ": a malformed token";
      return publish(std::vector<exec::ObjectStatus>{s});
    }
    publish(judge_->onObjectSegment(o, m.segment_id, m.step, *t, {m.goal.x, m.goal.y}, now()));
  }

  void onEntities(const ddace::EntityArray& m) {
    const exec::EntityObservation o = ros_exec::toObservation(m, spec_);
    judge_->onPositions(o.positions, o.tracked);
    publish(judge_->update(now()));
  }

  void publish(const std::vector<exec::ObjectStatus>& statuses) {
    for (const exec::ObjectStatus& s : statuses) {
      status_pubs_.at(s.entity).publish(ros_exec::statusMsg(s, spec_));
      if (s.state == exec::SegmentState::Failed) ROS_WARN("carried_objects: %s", s.message.c_str());
    }
  }

  task::TaskSpec spec_;
  std::unique_ptr<exec::CarriedObjects> judge_;
  std::vector<ros::Subscriber> subs_;
  std::map<int, ros::Publisher> status_pubs_;  ///< by object index
  ros::Subscriber entities_sub_;
  ros::Timer timer_;
};

CarriedObjectsNode::CarriedObjectsNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : impl_(std::make_unique<Impl>(nh, pnh)) {}

CarriedObjectsNode::~CarriedObjectsNode() = default;

}  // namespace ddace::nodes
