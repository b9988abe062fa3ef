// PathFollowerNode: see include/ddace/ros/path_follower.h. Each robot's control cycle is
// exec::RobotController's, what the node knows of the bodies and the step's segments
// exec::FollowerView's; the node converts messages to and from them.
#include "ddace/ros/path_follower.h"

#include <map>
#include <memory>

#include <ros/ros.h>
#include <std_msgs/Bool.h>

#include <ddace/CoordinatorState.h>

#include "ddace/exec/follower_view.h"
#include "ddace/exec/robot_controller.h"
#include "ddace/task/body_geometry.h"
#include "exec_conversions.h"
#include "params.h"

namespace ddace::nodes {

class PathFollowerNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    std::vector<std::string> names = rosparam::param(pnh, "robots", std::vector<std::string>{});
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    const bool every_robot = names.empty();
    double arrival_m = task::kDefaultArrivalRadius;
    std::map<std::string, task::Entity> kinds;  // the task's entities by name, when known
    if (every_robot || !task_path.empty()) {
      const task::TaskSpec spec = ros_exec::loadTaskSpec(task_path);
      for (const auto& e : spec.entities) {
        if (every_robot && e.kind == task::EntityKind::Robot) names.push_back(e.name);
        kinds[e.name] = e;
      }
      arrival_m = spec.arrival_radius;
    }
    if (names.empty()) throw Error("no robots to drive: set '" + pnh.resolveName("robots") + "' or a task with robots");
    params_.gains = ros_exec::loadFollowerGains(ros::NodeHandle(pnh, "gains"));
    params_.safety = ros_exec::loadSafetyParams(ros::NodeHandle(pnh, "safety"));
    if (!pnh.hasParam("gains/stop_radius_m")) params_.gains.stop_radius_m = task::stopRadius(arrival_m);
    const PathFollowerNode::Params defaults;
    rate_hz_ = rosparam::param(pnh, "rate_hz", defaults.rate_hz);
    pose_timeout_s_ = rosparam::param(pnh, "pose_timeout_s", defaults.pose_timeout_s);
    params_.stale_fail_s = rosparam::param(pnh, "stale_fail_s", defaults.stale_fail_s);
    status_every_ = std::max(1, rosparam::param(pnh, "status_every_cycles", defaults.status_every_cycles));
    loads_ride_ = rosparam::param(pnh, "loads_ride", defaults.loads_ride);
    for (const auto& [p, v] :
         {std::pair{"rate_hz", rate_hz_}, {"pose_timeout_s", pose_timeout_s_}, {"stale_fail_s", params_.stale_fail_s}})
      if (!(v > 0)) throw Error("parameter '" + pnh.resolveName(p) + "' must be positive");
    params_.validate();
    view_ = std::make_unique<exec::FollowerView>(kinds, arrival_m, params_.safety.endsAgainstReachM());
    for (const auto& name : names) {
      auto r = std::make_unique<Robot>(name, params_);
      r->wheels = nh.advertise<ddace::WheelCommand>("/robots/" + name + "/wheels", 10);
      r->status = nh.advertise<ddace::SegmentStatus>("/robots/" + name + "/segment_status", 20);
      Robot* raw = r.get();
      r->segment_sub = nh.subscribe<ddace::Segment>(
          "/robots/" + name + "/segment", 10, [this, raw](const ddace::Segment::ConstPtr& m) { onSegment(*raw, *m); });
      robots_[name] = std::move(r);
    }
    // The segments of the entities driven elsewhere (objects, other followers' robots):
    // where they end this step and which load a carrier carries. Forgotten when they end.
    for (const auto& [name, e] : kinds)
      if (e.kind != task::EntityKind::Goal && !robots_.count(name)) {
        subs_.push_back(nh.subscribe<ddace::Segment>(
            "/robots/" + name + "/segment", 10,
            [this, name = name](const ddace::Segment::ConstPtr& m) { noteSegment(name, *m); }));
        subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
            "/robots/" + name + "/segment_status", 20,
            [this, name = name](const ddace::SegmentStatus::ConstPtr& m) { noteStatus(name, *m); }));
      }
    subs_.push_back(nh.subscribe("/ddace/entities", 5, &Impl::onEntities, this));
    subs_.push_back(nh.subscribe("/ddace/estop", 5, &Impl::onEstop, this));
    subs_.push_back(nh.subscribe("/coordinator/state", 5, &Impl::onCoordinatorState, this));
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz_), &Impl::onTimer, this);
    ROS_INFO("path_follower: driving %zu robots at %.0f Hz (cruise %.3f m/s, stop radius %.3f m), safety filter %s",
             robots_.size(), rate_hz_, params_.gains.cruise_speed_mps, params_.gains.stop_radius_m,
             params_.safety.enabled ? "on" : "OFF");
  }

 private:
  struct Robot {
    Robot(const std::string& name, const exec::ControllerParams& p) : controller(name, p) {}
    exec::RobotController controller;
    ros::Publisher wheels, status;
    ros::Subscriber segment_sub;
    uint32_t segment_id = 0;
    int step = -1;
    uint64_t decided = ~0ULL;  ///< the step's version (FollowerView) its contacts were decided at
    exec::Pose2D pose;
    bool pose_known = false, pose_stale = true;
    ros::Time pose_time;
    int cycle = 0;
  };
  void publishWheels(Robot& r, const exec::WheelSpeeds& w) { r.wheels.publish(ros_exec::toMsg(w)); }
  void publishStatus(Robot& r, uint32_t id, uint8_t status, double progress, double dist, const std::string& msg) {
    r.status.publish(ros_exec::statusMsg(r.controller.name(), id, status, progress, dist, msg));
  }
  /// Cancels the robot's segment (if any) and zeroes its wheels now.
  void stopRobot(Robot& r, uint8_t status, const std::string& why) {
    if (r.controller.running()) publishStatus(r, r.segment_id, status, r.controller.progress(), 0.0, why);
    r.controller.cancel();
    view_->forget(r.controller.name());
    publishWheels(r, {});
  }

  void onSegment(Robot& r, const ddace::Segment& m) {
    if (m.mode == ddace::Segment::MODE_STOP)
      return stopRobot(r, ddace::SegmentStatus::ABORTED, "stopped by the coordinator");
    if (r.controller.running() && m.segment_id == r.segment_id) return;  // a re-sent copy of the running segment
    if (estopped_) {
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ABORTED, 0, 0, "e-stop is active");
      return publishWheels(r, {});
    }
    stopRobot(r, ddace::SegmentStatus::ABORTED, "replaced by segment " + std::to_string(m.segment_id));
    try {
      if (m.mode != ddace::Segment::MODE_FOLLOW) throw Error("unknown segment mode " + std::to_string(m.mode));
      const std::string& name = r.controller.name();
      if (!m.entity.empty() && m.entity != name)
        throw Error("segment for '" + m.entity + "' arrived on " + name + "'s topic");
      const exec::PlannedPath path = ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + name + "/segment");
      const bool given = m.arrival_radius_m > 0 && std::isfinite(m.arrival_radius_m);
      const double stop = given ? m.arrival_radius_m : params_.gains.stop_radius_m;  // the field is a stop radius
      const double toward = view_->stopToward(name, m.step, m.token.action, m.token.target, stop);
      r.controller.start(path, m.token.target, toward, stop, view_->stopAtPlace(stop));
      view_->noteSegment(name, m.segment_id, m.step, m.token.action, m.token.target, path.points.back(), path.points);
      r.segment_id = m.segment_id, r.step = m.step, r.decided = ~0ULL, r.cycle = 0;
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ACCEPTED, 0, 0, "");
    } catch (const std::exception& e) {
      ROS_ERROR("path_follower: %s: refusing segment %u: %s", r.controller.name().c_str(), m.segment_id, e.what());
      publishStatus(r, m.segment_id, ddace::SegmentStatus::FAILED, 0, 0, e.what());
      publishWheels(r, {});
    }
  }

  /// A segment of an entity driven elsewhere: a valid one is noted (FollowerView), MODE_STOP
  /// or a malformed one forgets its last.
  void noteSegment(const std::string& name, const ddace::Segment& m) {
    if (m.mode == ddace::Segment::MODE_FOLLOW) {
      try {
        const exec::PlannedPath p = ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + name + "/segment");
        if (p.points.empty()) throw Error("its path has no points");
        view_->noteSegment(name, m.segment_id, m.step, m.token.action, m.token.target, p.points.back(), p.points);
        return;
      } catch (const std::exception& e) {
        ROS_WARN("path_follower: ignoring segment %u of %s: %s", m.segment_id, name.c_str(), e.what());
      }
    }
    view_->forget(name);
  }
  void noteStatus(const std::string& name, const ddace::SegmentStatus& m) {
    if (m.status == ddace::SegmentStatus::DONE || m.status == ddace::SegmentStatus::FAILED ||
        m.status == ddace::SegmentStatus::ABORTED)
      view_->noteEnded(name, m.segment_id);
  }

  void onEntities(const ddace::EntityArray& m) {
    const ros::Time now = ros::Time::now();
    for (const auto& e : m.entities) {
      const bool finite = std::isfinite(e.pose.x) && std::isfinite(e.pose.y);
      const ros::Time seen =
          (!e.last_seen.isZero() && e.last_seen <= now) ? e.last_seen : now;  // never from the future
      view_->track(e.name, task::entityKindFromString(e.kind),
                   finite ? Eigen::Vector2d(e.pose.x, e.pose.y) : Eigen::Vector2d::Constant(NAN), e.stale,
                   seen.toSec());
      auto it = robots_.find(e.name);
      if (it == robots_.end()) continue;
      Robot& r = *it->second;
      const bool was_stale = r.pose_stale;
      r.pose_stale = e.stale || !finite || !std::isfinite(e.pose.theta);
      if (r.pose_stale && !was_stale && r.controller.running()) publishWheels(r, {});  // now, not next cycle
      if (finite && std::isfinite(e.pose.theta)) r.pose = {e.pose.x, e.pose.y, e.pose.theta}, r.pose_known = true;
      r.pose_time = now;
    }
  }

  /// The robots the coordinator lost for good stay obstacles where they were last seen.
  void onCoordinatorState(const ddace::CoordinatorState& m) {
    if (m.lost == lost_) return;
    lost_ = m.lost;
    for (const auto& n : view_->setLost(lost_))
      ROS_WARN("path_follower: /coordinator/state names '%s' lost, not a robot of the task: ignored", n.c_str());
    for (const auto& n : lost_)
      ROS_WARN("path_follower: %s is lost for good: kept as an obstacle where it was last seen", n.c_str());
  }

  void onEstop(const std_msgs::Bool& m) {
    if (m.data != estopped_) ROS_WARN("path_follower: e-stop %s", m.data ? "ACTIVE: zeroing every robot" : "released");
    estopped_ = m.data;
    if (estopped_)
      for (auto& [name, r] : robots_) stopRobot(*r, ddace::SegmentStatus::ABORTED, "e-stop");
  }

  void onTimer(const ros::TimerEvent&) {
    const ros::Time now = ros::Time::now();
    for (auto& [name, rp] : robots_) {
      Robot& r = *rp;
      if (estopped_ || !r.controller.running()) {
        publishWheels(r, {});
        continue;
      }
      // Nobody publishes this robot's segments any more: the coordinator died. Nobody would
      // stop the robot or hear its status: stop it here.
      if (r.segment_sub.getNumPublishers() == 0) {
        const std::string why = "the coordinator is gone (no publisher on " + r.segment_sub.getTopic() + ")";
        ROS_ERROR("path_follower: %s: %s: stopping", name.c_str(), why.c_str());
        stopRobot(r, ddace::SegmentStatus::ABORTED, why);
        continue;
      }
      double self_age = 1e9;
      others_ = view_->others(name, now.toSec(), self_age);
      const bool stale = !r.pose_known || r.pose_stale || (now - r.pose_time).toSec() > pose_timeout_s_;
      if (!stale && r.decided != view_->stepVersion(r.step)) {
        r.decided = view_->stepVersion(r.step);
        exec::MotionContacts c = view_->contacts(name, r.pose.position());
        c.load_rides = loads_ride_;
        r.controller.setContacts(std::move(c));
      }
      const uint32_t id = r.segment_id;
      const exec::ControlOutput c =
          r.controller.cycle(r.pose, stale, self_age, view_->radiusOf(name), others_, now.toSec());
      publishWheels(r, c.wheels);
      if (c.state == exec::MotionState::Failed || c.state == exec::MotionState::Done) view_->forget(name);
      if (c.state == exec::MotionState::Failed) {
        ROS_ERROR("path_follower: %s: %s: failing segment %u", name.c_str(), c.message.c_str(), id);
        publishStatus(r, id, ddace::SegmentStatus::FAILED, c.progress, c.distance_to_goal_m, c.message);
      } else if (c.state == exec::MotionState::Done) {
        if (!c.message.empty()) ROS_INFO("path_follower: %s: %s", name.c_str(), c.message.c_str());
        publishStatus(r, id, ddace::SegmentStatus::DONE, 1.0, c.distance_to_goal_m, c.message);
      } else if (c.waiting_stale) {
        ROS_WARN_THROTTLE(1.0,
                          "path_follower: %s: %s, wheels zero until a fresh pose comes (nothing to do if the camera "
                          "sees it again soon; if it lasts, the segment fails and the run says so)",
                          name.c_str(), c.message.c_str());
      } else {
        if (c.held) ROS_WARN_THROTTLE(1.0, "path_follower: %s: held by the safety filter", name.c_str());
        // A robot queued behind another of its step says for whom it stands still.
        const std::string why = c.waiting_for.empty() ? "" : c.message;
        if (!why.empty()) ROS_INFO_THROTTLE(1.0, "path_follower: %s", why.c_str());
        if (r.cycle++ % status_every_ == 0)
          publishStatus(r, id, ddace::SegmentStatus::RUNNING, c.progress, c.distance_to_goal_m, why);
      }
    }
  }

  std::map<std::string, std::unique_ptr<Robot>> robots_;
  std::unique_ptr<exec::FollowerView> view_;
  std::vector<std::string> lost_;         ///< the coordinator's lost robots, as last published
  std::vector<exec::SafetyBody> others_;  ///< scratch of onTimer
  std::vector<ros::Subscriber> subs_;
  exec::ControllerParams params_;
  bool loads_ride_ = false;
  double rate_hz_ = 0, pose_timeout_s_ = 0;
  int status_every_ = 1;
  bool estopped_ = false;
  ros::Timer timer_;
};

PathFollowerNode::PathFollowerNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

PathFollowerNode::~PathFollowerNode() = default;

}  // namespace ddace::nodes
