// PathFollowerNode: see include/ddace/ros/path_follower.h.
#include "ddace/ros/path_follower.h"

#include <map>
#include <set>
#include <memory>

#include <ros/ros.h>
#include <std_msgs/Bool.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

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
        task_entities_[e.name] = e;
      }
      default_arrival_m_ = spec.arrival_radius;
    }
    if (names.empty()) throw Error("no robots to drive: set '" + pnh.resolveName("robots") + "' or a task with robots");
    gains_ = ros_exec::loadFollowerGains(ros::NodeHandle(pnh, "gains"));
    safety_ = ros_exec::loadSafetyParams(ros::NodeHandle(pnh, "safety"));
    if (!pnh.hasParam("gains/arrival_radius_m")) gains_.arrival_radius_m = default_arrival_m_;
    const PathFollowerNode::Params defaults;
    rate_hz_ = rosparam::param(pnh, "rate_hz", defaults.rate_hz);
    pose_timeout_s_ = rosparam::param(pnh, "pose_timeout_s", defaults.pose_timeout_s);
    stale_fail_s_ = rosparam::param(pnh, "stale_fail_s", defaults.stale_fail_s);
    status_every_ = std::max(1, rosparam::param(pnh, "status_every_cycles", defaults.status_every_cycles));
    if (!(rate_hz_ > 0)) throw Error("parameter '" + pnh.resolveName("rate_hz") + "' must be positive");
    if (!(pose_timeout_s_ > 0)) throw Error("parameter '" + pnh.resolveName("pose_timeout_s") + "' must be positive");
    if (!(stale_fail_s_ > 0)) throw Error("parameter '" + pnh.resolveName("stale_fail_s") + "' must be positive");

    for (const auto& name : names) {
      auto r = std::make_unique<Robot>();
      r->name = name;
      r->safety = std::make_unique<exec::SafetyFilter>(safety_, gains_.wheel_base_m, gains_.max_wheel_speed_mps,
                                                       gains_.max_turn_rate_radps);
      r->wheels = nh.advertise<ddace::WheelCommand>("/robots/" + name + "/wheels", 10);
      r->status = nh.advertise<ddace::SegmentStatus>("/robots/" + name + "/segment_status", 20);
      Robot* raw = r.get();
      r->segment_sub = nh.subscribe<ddace::Segment>(
          "/robots/" + name + "/segment", 10, [this, raw](const ddace::Segment::ConstPtr& m) { onSegment(*raw, *m); });
      robots_[name] = std::move(r);
    }
    // The other entities' segments (objects, robots driven elsewhere): where they end
    // (bodies a motion ends against) and which load a carrier carries.
    // A segment is forgotten when it ends (its status DONE, FAILED or ABORTED) or another
    // replaces it.
    for (const auto& [name, e] : task_entities_)
      if (e.kind != task::EntityKind::Goal && !robots_.count(name)) {
        object_subs_.push_back(nh.subscribe<ddace::Segment>(
            "/robots/" + name + "/segment", 10,
            [this, name = name, object = e.kind == task::EntityKind::Object](const ddace::Segment::ConstPtr& m) {
              noteSegment(name, object, *m);
            }));
        object_subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
            "/robots/" + name + "/segment_status", 20,
            [this, name = name](const ddace::SegmentStatus::ConstPtr& m) { noteStatus(name, *m); }));
      }
    entities_sub_ = nh.subscribe("/ddace/entities", 5, &Impl::onEntities, this);
    estop_sub_ = nh.subscribe("/ddace/estop", 5, &Impl::onEstop, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz_), &Impl::onTimer, this);
    ROS_INFO(
        "path_follower: driving %zu robots at %.0f Hz (cruise %.3f m/s, lookahead %.3f m, arrival %.3f m), "
        "safety filter %s (margin %.3f m)",
        robots_.size(), rate_hz_, gains_.cruise_speed_mps, gains_.lookahead_m, gains_.arrival_radius_m,
        safety_.enabled ? "on" : "OFF", safety_.margin_m);
  }

 private:
  struct Robot {
    std::string name;
    ros::Publisher wheels, status;
    ros::Subscriber segment_sub;
    std::unique_ptr<exec::PathFollower> follower;  ///< null = no segment
    std::unique_ptr<exec::SafetyFilter> safety;    ///< between the follower and the wheels
    std::string target;                            ///< the segment's target entity ("" = none)
    int step = -1;                                 ///< the segment's step
    std::string action;                            ///< the segment's token's action
    /// Decided at the segment's first filtered cycle: the bodies its end point touches
    /// (standing there, or ending there in this step) and its load's.
    bool decided = false;
    std::set<std::string> ends_against, load_ends_against;
    std::string load;                ///< the object it carries ("" = none)
    Eigen::Vector2d load_end{0, 0};  ///< its load's end point, as decided
    uint32_t segment_id = 0;
    exec::Pose2D pose;
    bool pose_known = false, pose_stale = true;
    ros::Time pose_time;
    ros::Time stale_since;
    bool stale_counting = false;
    int cycle = 0;
  };

  void publishWheels(Robot& r, double left, double right) {
    ddace::WheelCommand w;
    w.header.stamp = ros::Time::now();
    w.left_mps = left;
    w.right_mps = right;
    r.wheels.publish(w);
  }

  void publishStatus(Robot& r, uint32_t id, uint8_t status, double progress, double dist, const std::string& msg) {
    ddace::SegmentStatus s;
    s.header.stamp = ros::Time::now();
    s.entity = r.name;
    s.segment_id = id;
    s.status = status;
    s.progress = progress;
    s.distance_to_goal_m = dist;
    s.message = msg;
    r.status.publish(s);
  }

  /// Cancels the robot's segment (if any) and zeroes its wheels now.
  void stopRobot(Robot& r, uint8_t status, const std::string& why) {
    if (r.follower) {
      publishStatus(r, r.segment_id, status, r.follower->progress(), 0.0, why);
      r.follower.reset();
    }
    publishWheels(r, 0, 0);
  }

  void onSegment(Robot& r, const ddace::Segment& m) {
    if (m.mode == ddace::Segment::MODE_STOP) {
      stopRobot(r, ddace::SegmentStatus::ABORTED, "stopped by the coordinator");
      return;
    }
    if (r.follower && m.segment_id == r.segment_id) return;  // a re-sent copy of the running segment
    if (estopped_) {
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ABORTED, 0, 0, "e-stop is active");
      publishWheels(r, 0, 0);
      return;
    }
    if (r.follower)
      publishStatus(r, r.segment_id, ddace::SegmentStatus::ABORTED, r.follower->progress(), 0,
                    "replaced by segment " + std::to_string(m.segment_id));
    r.follower.reset();
    try {
      if (m.mode != ddace::Segment::MODE_FOLLOW) throw Error("unknown segment mode " + std::to_string(m.mode));
      if (!m.entity.empty() && m.entity != r.name)
        throw Error("segment for '" + m.entity + "' arrived on " + r.name + "'s topic");
      const exec::PlannedPath path = ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + r.name + "/segment");
      exec::FollowerGains g = gains_;
      if (m.arrival_radius_m > 0 && std::isfinite(m.arrival_radius_m)) g.arrival_radius_m = m.arrival_radius_m;
      auto f = std::make_unique<exec::PathFollower>(g);
      f->setPath(path);
      r.follower = std::move(f);
      r.target = m.token.target;
      r.step = m.step;
      r.action = m.token.action;
      r.decided = false;
      r.load.clear();
      r.safety->reset();
      r.segment_id = m.segment_id;
      r.cycle = 0;
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ACCEPTED, 0, 0, "");
      redecideStep(r.name, m.step);  // validated and accepted: the others of its step decide again
    } catch (const std::exception& e) {
      ROS_ERROR("path_follower: %s: refusing segment %u: %s", r.name.c_str(), m.segment_id, e.what());
      publishStatus(r, m.segment_id, ddace::SegmentStatus::FAILED, 0, 0, e.what());
      publishWheels(r, 0, 0);
    }
  }

  /// The running segment of an entity driven elsewhere (an object, a robot of another
  /// follower): its id, step, token and end point.
  struct ObjectSegment {
    uint32_t id = 0;
    int step = -1;
    std::string action, target;
    Eigen::Vector2d end{0, 0};
    bool object = false;
  };
  /// The segments of the entities driven elsewhere, as they are sent: a valid one replaces
  /// the entity's last; MODE_STOP, or one its own executor will refuse (a malformed path),
  /// forgets it. A new one of a step makes the robots here running that step decide again
  /// what they end against (a step's segments arrive one by one, in any order, within
  /// milliseconds).
  void noteSegment(const std::string& name, bool object, const ddace::Segment& m) {
    const auto ended = ended_segment_.find(name);
    if (m.mode == ddace::Segment::MODE_FOLLOW && ended != ended_segment_.end() && ended->second == m.segment_id) {
      // Its end status came first (another connection), or the coordinator re-sent it:
      // it ended, the entity stands.
      ROS_DEBUG("path_follower: segment %u of %s has already ended", m.segment_id, name.c_str());
      forgetSegment(name);  // an older one whose end status was lost: it stands all the same
      return;
    }
    if (m.mode == ddace::Segment::MODE_FOLLOW) {
      try {
        const exec::PlannedPath p = ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + name + "/segment");
        if (p.points.empty()) throw Error("its path has no points");
        object_segments_[name] = {m.segment_id, m.step, m.token.action, m.token.target, p.points.back(), object};
        redecideStep(name, m.step);
        return;
      } catch (const std::exception& e) {
        ROS_WARN("path_follower: ignoring segment %u of %s: %s", m.segment_id, name.c_str(), e.what());
      }
    }
    forgetSegment(name);
  }
  /// The status of an entity driven elsewhere: its segment ended, it stands where it is.
  /// An end status may arrive before its segment (separate connections): remembered, the
  /// segment is ignored when it comes.
  void noteStatus(const std::string& name, const ddace::SegmentStatus& m) {
    if (m.status != ddace::SegmentStatus::DONE && m.status != ddace::SegmentStatus::FAILED &&
        m.status != ddace::SegmentStatus::ABORTED)
      return;
    ended_segment_[name] = m.segment_id;
    const auto it = object_segments_.find(name);
    if (it != object_segments_.end() && it->second.id == m.segment_id) forgetSegment(name);
  }
  void forgetSegment(const std::string& name) {
    if (!object_segments_.erase(name)) return;
    for (auto& [other, r] : robots_)  // a carrier of it decides again: no load any more
      if (r->load == name) r->decided = false;
  }
  /// The robots here running step `step` decide again what they end against: `name`'s
  /// segment of that step arrived.
  void redecideStep(const std::string& name, int step) {
    for (auto& [other, r] : robots_)
      if (other != name && r->follower && r->step == step) r->decided = false;
  }

  /// Where body `name` ends this step: its running segment's end point, else where it is
  /// now.
  Eigen::Vector2d finalPosition(const std::string& name, const Eigen::Vector2d& now) const {
    if (auto it = robots_.find(name); it != robots_.end())
      return it->second->follower ? it->second->follower->endPoint() : now;
    if (auto it = object_segments_.find(name); it != object_segments_.end()) return it->second.end;
    return now;
  }
  /// Whether body `name` stands still: no running segment (exec::SafetyBody::standing).
  bool standing(const std::string& name) const {
    if (auto it = robots_.find(name); it != robots_.end()) return !it->second->follower;
    return !object_segments_.count(name);
  }

  /// Once per segment, at its first filtered cycle and again when another segment of its
  /// step arrives (never from where bodies are while they move): its load and the bodies its end point and its load's
  /// touch (exec::segmentContacts, as exec::BodiesExecution decides them for a step).
  void decide(Robot& r, double self_radius) {
    r.decided = true;
    std::vector<exec::BodyAtStart> at;
    for (const auto& [name, t] : bodies_) {
      if (name == r.name) continue;
      exec::BodyAtStart b;
      b.name = name;
      b.position = t.body.position;
      b.final_position = finalPosition(name, t.body.position);
      b.radius_m = t.body.radius_m;
      if (auto o = object_segments_.find(name); o != object_segments_.end() && o->second.object) {
        b.object = true;
        b.step = o->second.step;
        b.action = o->second.action;
        b.target = o->second.target;
      }
      at.push_back(b);
    }
    const exec::SegmentContacts c =
        exec::segmentContacts(r.pose.position(), self_radius, r.follower->endPoint(), r.step, r.action, r.target, at,
                              safety_.margin_m, default_arrival_m_);
    r.load = c.load;
    if (auto it = object_segments_.find(r.load); !r.load.empty() && it != object_segments_.end())
      r.load_end = it->second.end;
    else r.load.clear();
    r.ends_against = {c.ends_against.begin(), c.ends_against.end()};
    r.load_ends_against = {c.load_ends_against.begin(), c.load_ends_against.end()};
  }

  /// A tracked body as the safety filters see it (robots, objects; goals are flat).
  struct Tracked {
    exec::SafetyBody body;
    ros::Time seen;  ///< when measured (the tracker's last_seen, else when received)
  };

  void onEntities(const ddace::EntityArray& m) {
    const ros::Time now = ros::Time::now();
    for (const auto& e : m.entities) {
      const bool ok = std::isfinite(e.pose.x) && std::isfinite(e.pose.y);
      auto known = task_entities_.find(e.name);
      task::Entity te;
      if (known != task_entities_.end()) {
        te = known->second;
      } else {
        te.name = e.name;
        te.kind = task::entityKindFromString(e.kind).value_or(task::EntityKind::Object);  // unknown kind: keep off it
      }
      const exec::BodyShape shape = exec::bodyShape(te);
      if (shape.obstacle) {
        Tracked& t = bodies_[e.name];
        t.body.name = e.name;
        t.body.radius_m = shape.radius_m;
        t.body.robot = te.kind == task::EntityKind::Robot;
        if (ok) t.body.position = {e.pose.x, e.pose.y};
        t.body.stale = e.stale || !ok;
        // Trust a measurement time only when it is not in the future.
        t.seen = (!e.last_seen.isZero() && e.last_seen <= now) ? e.last_seen : now;
      }
    }
    for (const auto& e : m.entities) {
      auto it = robots_.find(e.name);
      if (it == robots_.end()) continue;
      Robot& r = *it->second;
      const bool finite = std::isfinite(e.pose.x) && std::isfinite(e.pose.y) && std::isfinite(e.pose.theta);
      const bool was_stale = r.pose_stale;
      r.pose_stale = e.stale || !finite;
      // A pose gone stale stops the robot now, not at the next cycle.
      if (r.pose_stale && !was_stale && r.follower) publishWheels(r, 0, 0);
      if (finite) r.pose = {e.pose.x, e.pose.y, e.pose.theta};
      r.pose_known = r.pose_known || finite;
      r.pose_time = now;
    }
  }

  void onEstop(const std_msgs::Bool& m) {
    if (m.data && !estopped_) ROS_WARN("path_follower: E-STOP: zeroing every robot");
    if (!m.data && estopped_) ROS_INFO("path_follower: e-stop released");
    estopped_ = m.data;
    if (estopped_)
      for (auto& [name, r] : robots_) stopRobot(*r, ddace::SegmentStatus::ABORTED, "e-stop");
  }

  void onTimer(const ros::TimerEvent&) {
    const ros::Time now = ros::Time::now();
    for (auto& [name, rp] : robots_) {
      Robot& r = *rp;
      if (estopped_ || !r.follower) {
        publishWheels(r, 0, 0);
        continue;
      }
      // Nobody publishes this robot's segments any more: the coordinator died (its link
      // dropped). Nobody would stop the robot or hear its status: stop it here.
      if (r.segment_sub.getNumPublishers() == 0) {
        ROS_ERROR("path_follower: %s: the coordinator is gone (no publisher on %s): stopping", name.c_str(),
                  r.segment_sub.getTopic().c_str());
        stopRobot(r, ddace::SegmentStatus::ABORTED,
                  "the coordinator is gone (no publisher on " + r.segment_sub.getTopic() + ")");
        continue;
      }
      const bool stale = !r.pose_known || r.pose_stale || (now - r.pose_time).toSec() > pose_timeout_s_;
      if (stale) {
        if (!r.stale_counting) r.stale_since = now, r.stale_counting = true;
        publishWheels(r, 0, 0);
        const double for_s = (now - r.stale_since).toSec();
        if (for_s > stale_fail_s_) {
          ROS_ERROR("path_follower: %s: pose stale for %.2f s, failing segment %u", name.c_str(), for_s, r.segment_id);
          stopRobot(r, ddace::SegmentStatus::FAILED, "pose of " + name + " stale for longer than stale_fail_s");
        } else {
          ROS_WARN_THROTTLE(1.0, "path_follower: %s: pose stale, wheels zero", name.c_str());
        }
        continue;
      }
      const exec::FollowerOutput o = r.follower->compute(r.pose);
      exec::WheelSpeeds wheels = o.wheels;
      if (!o.done) {
        const exec::SafetyCommand c = filterCommand(r, o.wheels, now);
        if (c.deadlock) {
          char where[64];
          std::snprintf(where, sizeof where, ", %.1f cm from its end point", 100 * o.distance_to_goal_m);
          ROS_ERROR("path_follower: %s: %s%s: failing segment %u", name.c_str(), c.reason.c_str(), where, r.segment_id);
          stopRobot(r, ddace::SegmentStatus::FAILED, c.reason + where);
          continue;
        }
        if (c.stale) {  // a body nearby is stale: as for the robot's own pose
          if (!r.stale_counting) r.stale_since = now, r.stale_counting = true;
          publishWheels(r, 0, 0);
          const double for_s = (now - r.stale_since).toSec();
          if (for_s > stale_fail_s_) {
            ROS_ERROR("path_follower: %s: %s for %.2f s, failing segment %u", name.c_str(), c.reason.c_str(), for_s,
                      r.segment_id);
            stopRobot(r, ddace::SegmentStatus::FAILED, c.reason + " for longer than stale_fail_s");
          } else {
            ROS_WARN_THROTTLE(1.0, "path_follower: %s: %s, wheels zero", name.c_str(), c.reason.c_str());
          }
          continue;
        }
        if (exec::endedAtContact(c, o.distance_to_goal_m, r.follower->gains().arrival_radius_m)) {
          // A motion toward a body ends at contact with it: held there by a body it ends
          // against, within the segment's stop radius of its end point, it has arrived (the
          // coordinator checks the DONE within its arrival radius plus the tolerance).
          ROS_INFO("path_follower: %s: ended at contact with %s, %.1f cm from its end point", name.c_str(),
                   c.at_contact_with.c_str(), 100 * o.distance_to_goal_m);
          r.stale_counting = false;
          publishWheels(r, 0, 0);
          publishStatus(r, r.segment_id, ddace::SegmentStatus::DONE, 1.0, o.distance_to_goal_m,
                        "ended at contact with " + c.at_contact_with);
          r.follower.reset();
          continue;
        }
        if (c.blocked)
          ROS_WARN_THROTTLE(1.0, "path_follower: %s: held by the safety filter (%zu bodies)", name.c_str(),
                            c.blocking.size());
        wheels = c.wheels;
      }
      r.stale_counting = false;
      publishWheels(r, wheels.left_mps, wheels.right_mps);
      if (o.done) {
        publishStatus(r, r.segment_id, ddace::SegmentStatus::DONE, 1.0, o.distance_to_goal_m, "");
        r.follower.reset();
      } else if (r.cycle++ % status_every_ == 0) {
        publishStatus(r, r.segment_id, ddace::SegmentStatus::RUNNING, o.progress, o.distance_to_goal_m, "");
      }
    }
  }

  /// The follower's command through the robot's own safety filter, from the tracked
  /// poses of every other body.
  exec::SafetyCommand filterCommand(Robot& r, const exec::WheelSpeeds& nominal, const ros::Time& now) {
    others_.clear();
    double self_age = 1e9, self_radius = exec::bodyShape(task::Entity{r.name, task::EntityKind::Robot, ""}).radius_m;
    for (auto& [name, t] : bodies_) {
      const double age = (now - t.seen).toSec();
      if (name == r.name) {
        self_age = t.body.stale ? 1e9 : age;
        self_radius = t.body.radius_m;
        continue;
      }
      others_.push_back(t.body);
      others_.back().age_s = age;
    }
    // The bodies the motion ends against (a robot already on the goal) may be touched,
    // decided once for the segment; its load is part of its body.
    if (!r.decided) decide(r, self_radius);
    const exec::SafetyBody* load = nullptr;
    for (exec::SafetyBody& b : others_)
      if (b.name == r.load) load = &b;
    const Eigen::Vector2d end = r.follower->endPoint();
    for (exec::SafetyBody& b : others_) {  // touched as its ending: while it is at the end point
      b.standing = standing(b.name);
      b.touchable = r.ends_against.count(b.name) > 0 &&
                    exec::endsAgainst(end, self_radius, b.position, b.radius_m, safety_.margin_m);
      b.load_touchable = load && r.load_ends_against.count(b.name) > 0 &&
                         exec::endsAgainst(r.load_end, load->radius_m, b.position, b.radius_m, safety_.margin_m);
    }
    return r.safety->filter(r.name, r.pose, self_radius, self_age, nominal,
                            r.follower->progress() * r.follower->lengthM(), others_, r.target, now.toSec(), load);
  }

  std::map<std::string, std::unique_ptr<Robot>> robots_;
  std::map<std::string, task::Entity> task_entities_;     ///< by name, when the task is known
  std::map<std::string, Tracked> bodies_;                 ///< every tracked body by name
  std::vector<exec::SafetyBody> others_;                  ///< scratch of filterCommand
  std::map<std::string, ObjectSegment> object_segments_;  ///< running ones, by name (driven elsewhere)
  std::map<std::string, uint32_t> ended_segment_;         ///< the last segment id reported ended, by name
  std::vector<ros::Subscriber> object_subs_;
  exec::FollowerGains gains_;
  exec::SafetyParams safety_;
  double default_arrival_m_ = task::kDefaultArrivalRadius;
  double rate_hz_ = 0, pose_timeout_s_ = 0, stale_fail_s_ = 0;  // set from the parameters
  int status_every_ = 1;
  bool estopped_ = false;
  ros::Subscriber entities_sub_, estop_sub_;
  ros::Timer timer_;
};

PathFollowerNode::PathFollowerNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

PathFollowerNode::~PathFollowerNode() = default;

}  // namespace ddace::nodes
