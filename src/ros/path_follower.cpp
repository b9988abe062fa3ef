// PathFollowerNode: see include/ddace/ros/path_follower.h. Each robot's control cycle is
// exec::RobotController's; the node converts messages, keeps the tracked bodies and the
// step's segments (where the step's bodies end), and publishes what the controller decides.
#include "ddace/ros/path_follower.h"

#include <map>
#include <memory>

#include <ros/ros.h>
#include <std_msgs/Bool.h>

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
    if (every_robot || !task_path.empty()) {
      const task::TaskSpec spec = ros_exec::loadTaskSpec(task_path);
      for (const auto& e : spec.entities) {
        if (every_robot && e.kind == task::EntityKind::Robot) names.push_back(e.name);
        kinds_[e.name] = e;
      }
      arrival_m_ = spec.arrival_radius;
    }
    if (names.empty()) throw Error("no robots to drive: set '" + pnh.resolveName("robots") + "' or a task with robots");
    params_.gains = ros_exec::loadFollowerGains(ros::NodeHandle(pnh, "gains"));
    params_.safety = ros_exec::loadSafetyParams(ros::NodeHandle(pnh, "safety"));
    if (!pnh.hasParam("gains/arrival_radius_m")) params_.gains.arrival_radius_m = arrival_m_;
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
    for (const auto& [name, e] : kinds_)
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
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz_), &Impl::onTimer, this);
    ROS_INFO("path_follower: driving %zu robots at %.0f Hz (cruise %.3f m/s, stop radius %.3f m), safety filter %s",
             robots_.size(), rate_hz_, params_.gains.cruise_speed_mps, params_.gains.arrival_radius_m,
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
    std::string action;
    bool decided = false;  ///< what its segment may touch, for the step's segments so far
    exec::Pose2D pose;
    bool pose_known = false, pose_stale = true;
    ros::Time pose_time;
    int cycle = 0;
  };
  /// The running segment of an entity driven elsewhere.
  struct OtherSegment {
    uint32_t id = 0;
    int step = -1;
    std::string action, target;
    Eigen::Vector2d end{0, 0};
  };
  struct Tracked {
    exec::SafetyBody body;
    ros::Time seen;  ///< when measured (the tracker's last_seen, else when received)
  };

  void publishWheels(Robot& r, const exec::WheelSpeeds& w) { r.wheels.publish(ros_exec::toMsg(w)); }
  void publishStatus(Robot& r, uint32_t id, uint8_t status, double progress, double dist, const std::string& msg) {
    r.status.publish(ros_exec::statusMsg(r.controller.name(), id, status, progress, dist, msg));
  }
  /// Cancels the robot's segment (if any) and zeroes its wheels now.
  void stopRobot(Robot& r, uint8_t status, const std::string& why) {
    if (r.controller.running()) publishStatus(r, r.segment_id, status, r.controller.progress(), 0.0, why);
    r.controller.cancel();
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
      const double stop = given ? m.arrival_radius_m : params_.gains.arrival_radius_m;
      r.controller.start(path, m.token.target, stopToward(r, m.step, m.token, path.points.back(), stop), stop);
      r.segment_id = m.segment_id, r.step = m.step, r.action = m.token.action, r.decided = false, r.cycle = 0;
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ACCEPTED, 0, 0, "");
      redecideStep(name, m.step);  // the others of its step decide again with its end point
    } catch (const std::exception& e) {
      ROS_ERROR("path_follower: %s: refusing segment %u: %s", r.controller.name().c_str(), m.segment_id, e.what());
      publishStatus(r, m.segment_id, ddace::SegmentStatus::FAILED, 0, 0, e.what());
      publishWheels(r, {});
    }
  }

  /// A segment of an entity driven elsewhere: a valid one replaces its last, MODE_STOP or a
  /// malformed one forgets it; one whose end status came first (another connection) is
  /// ended already. A step's segments arrive one by one: its robots here decide again.
  void noteSegment(const std::string& name, const ddace::Segment& m) {
    const auto ended = ended_.find(name);
    if (m.mode == ddace::Segment::MODE_FOLLOW && !(ended != ended_.end() && ended->second == m.segment_id)) {
      try {
        const exec::PlannedPath p = ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + name + "/segment");
        if (p.points.empty()) throw Error("its path has no points");
        others_segments_[name] = {m.segment_id, m.step, m.token.action, m.token.target, p.points.back()};
        return redecideStep(name, m.step);
      } catch (const std::exception& e) {
        ROS_WARN("path_follower: ignoring segment %u of %s: %s", m.segment_id, name.c_str(), e.what());
      }
    }
    forgetSegment(name);
  }
  void noteStatus(const std::string& name, const ddace::SegmentStatus& m) {
    if (m.status != ddace::SegmentStatus::DONE && m.status != ddace::SegmentStatus::FAILED &&
        m.status != ddace::SegmentStatus::ABORTED)
      return;
    ended_[name] = m.segment_id;
    if (auto it = others_segments_.find(name); it != others_segments_.end() && it->second.id == m.segment_id)
      forgetSegment(name);
  }
  void forgetSegment(const std::string& name) {
    if (!others_segments_.erase(name)) return;
    for (auto& [other, r] : robots_)  // a carrier of it decides again: no load any more
      if (r->controller.contacts().load == name) r->decided = false;
  }
  void redecideStep(const std::string& name, int step) {
    for (auto& [other, r] : robots_)
      if (other != name && r->controller.running() && r->step == step) r->decided = false;
  }

  /// r's stop radius toward the target of `token` ending at `end` (task::stopRadiusToward,
  /// the target where it ends); a goal is driven onto, and a carrier's load (an object's
  /// segment of the step known now) is what ends at the target: `stop`.
  double stopToward(const Robot& r, int step, const ddace::Token& token, const Eigen::Vector2d& end,
                    double stop) const {
    const std::string& target = token.target;
    const auto body = bodies_.find(target);
    if (body == bodies_.end()) return stop;
    for (const auto& [name, o] : others_segments_)
      if (o.step == step && o.action == token.action && o.target == target && kinds_.count(name) &&
          kinds_.at(name).kind == task::EntityKind::Object)
        return stop;
    Eigen::Vector2d at = body->second.body.position;
    if (auto o = others_segments_.find(target); o != others_segments_.end()) at = o->second.end;
    if (auto t = robots_.find(target); t != robots_.end() && t->second->controller.running())
      at = t->second->controller.endPoint();
    const double contact = radiusOf(r.controller.name()) + body->second.body.radius_m;
    return task::stopRadiusToward(stop, std::max(task::kArrivalToleranceM, arrival_m_ - stop),
                                  task::togetherDistance(contact, arrival_m_), (end - at).norm());
  }
  /// A robot's body radius: as tracked, else a Hamster's.
  double radiusOf(const std::string& name) const {
    const auto t = bodies_.find(name);
    return t != bodies_.end() ? t->second.body.radius_m
                              : exec::bodyShape(task::Entity{name, task::EntityKind::Robot, ""}).radius_m;
  }

  /// What robot r's motion may touch, from where the step's bodies end (exec::motionContacts).
  void decide(Robot& r, double self_radius) {
    r.decided = true;
    std::vector<exec::BodyAtStart> at;
    for (const auto& [name, t] : bodies_) {
      if (name == r.controller.name()) continue;
      exec::BodyAtStart b;
      b.name = name, b.position = b.final_position = t.body.position, b.radius_m = t.body.radius_m;
      if (auto it = robots_.find(name); it != robots_.end() && it->second->controller.running())
        b.final_position = it->second->controller.endPoint();
      if (auto o = others_segments_.find(name); o != others_segments_.end()) {
        b.final_position = o->second.end;
        b.object = kinds_.count(name) && kinds_.at(name).kind == task::EntityKind::Object;
        b.step = o->second.step, b.action = o->second.action, b.target = o->second.target;
      }
      at.push_back(b);
    }
    exec::MotionContacts c =
        exec::motionContacts(r.pose.position(), self_radius, r.controller.endPoint(), r.step, r.action,
                             r.controller.target(), at, params_.safety.margin_m, arrival_m_);
    c.load_rides = loads_ride_, r.controller.setContacts(std::move(c));
  }

  void onEntities(const ddace::EntityArray& m) {
    const ros::Time now = ros::Time::now();
    for (const auto& e : m.entities) {
      const bool finite = std::isfinite(e.pose.x) && std::isfinite(e.pose.y);
      task::Entity te{e.name, task::entityKindFromString(e.kind).value_or(task::EntityKind::Object), ""};
      if (auto known = kinds_.find(e.name); known != kinds_.end()) te = known->second;  // unknown kind: keep off it
      if (const exec::BodyShape shape = exec::bodyShape(te); shape.obstacle) {
        Tracked& t = bodies_[e.name];
        t.body.name = e.name;
        t.body.radius_m = shape.radius_m;
        t.body.robot = te.kind == task::EntityKind::Robot;
        if (finite) t.body.position = {e.pose.x, e.pose.y};
        t.body.stale = e.stale || !finite;
        t.seen = (!e.last_seen.isZero() && e.last_seen <= now) ? e.last_seen : now;  // never from the future
      }
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
      others_.clear();
      double self_age = 1e9;
      const double self_radius = radiusOf(name);
      for (auto& [other, t] : bodies_) {
        if (other == name) {
          self_age = t.body.stale ? 1e9 : (now - t.seen).toSec();
          continue;
        }
        others_.push_back(t.body);
        others_.back().age_s = (now - t.seen).toSec();
        auto it = robots_.find(other);
        others_.back().standing =
            it != robots_.end() ? !it->second->controller.running() : !others_segments_.count(other);
      }
      const bool stale = !r.pose_known || r.pose_stale || (now - r.pose_time).toSec() > pose_timeout_s_;
      if (!stale && !r.decided) decide(r, self_radius);
      const uint32_t id = r.segment_id;
      const exec::ControlOutput c = r.controller.cycle(r.pose, stale, self_age, self_radius, others_, now.toSec());
      publishWheels(r, c.wheels);
      if (c.state == exec::MotionState::Failed) {
        ROS_ERROR("path_follower: %s: %s: failing segment %u", name.c_str(), c.message.c_str(), id);
        publishStatus(r, id, ddace::SegmentStatus::FAILED, c.progress, c.distance_to_goal_m, c.message);
      } else if (c.state == exec::MotionState::Done) {
        if (!c.message.empty()) ROS_INFO("path_follower: %s: %s", name.c_str(), c.message.c_str());
        publishStatus(r, id, ddace::SegmentStatus::DONE, 1.0, c.distance_to_goal_m, c.message);
      } else if (c.waiting_stale) {
        ROS_WARN_THROTTLE(1.0, "path_follower: %s: %s, wheels zero", name.c_str(), c.message.c_str());
      } else {
        if (c.held) ROS_WARN_THROTTLE(1.0, "path_follower: %s: held by the safety filter", name.c_str());
        if (r.cycle++ % status_every_ == 0)
          publishStatus(r, id, ddace::SegmentStatus::RUNNING, c.progress, c.distance_to_goal_m, "");
      }
    }
  }

  std::map<std::string, std::unique_ptr<Robot>> robots_;
  std::map<std::string, task::Entity> kinds_;            ///< the task's entities by name, when known
  std::map<std::string, Tracked> bodies_;                ///< every tracked body by name
  std::vector<exec::SafetyBody> others_;                 ///< scratch of onTimer
  std::map<std::string, OtherSegment> others_segments_;  ///< running ones of entities driven elsewhere
  std::map<std::string, uint32_t> ended_;                ///< the last segment id reported ended, by name
  std::vector<ros::Subscriber> subs_;
  exec::ControllerParams params_;
  double arrival_m_ = task::kDefaultArrivalRadius;
  bool loads_ride_ = false;
  double rate_hz_ = 0, pose_timeout_s_ = 0;
  int status_every_ = 1;
  bool estopped_ = false;
  ros::Timer timer_;
};

PathFollowerNode::PathFollowerNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

PathFollowerNode::~PathFollowerNode() = default;

}  // namespace ddace::nodes
