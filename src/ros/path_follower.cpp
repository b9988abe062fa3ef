// PathFollowerNode: see include/ddace/ros/path_follower.h.
#include "ddace/ros/path_follower.h"

#include <map>
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
    if (names.empty()) {
      const task::TaskSpec spec = ros_exec::loadTaskSpec(rosparam::param<std::string>(pnh, "task", ""));
      for (const auto& e : spec.entities)
        if (e.kind == task::EntityKind::Robot) names.push_back(e.name);
      default_arrival_m_ = spec.arrival_radius;
    }
    if (names.empty()) throw Error("no robots to drive: set '" + pnh.resolveName("robots") + "' or a task with robots");
    gains_ = ros_exec::loadFollowerGains(ros::NodeHandle(pnh, "gains"));
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
      r->wheels = nh.advertise<ddace::WheelCommand>("/robots/" + name + "/wheels", 10);
      r->status = nh.advertise<ddace::SegmentStatus>("/robots/" + name + "/segment_status", 20);
      Robot* raw = r.get();
      r->segment_sub = nh.subscribe<ddace::Segment>(
          "/robots/" + name + "/segment", 10, [this, raw](const ddace::Segment::ConstPtr& m) { onSegment(*raw, *m); });
      robots_[name] = std::move(r);
    }
    entities_sub_ = nh.subscribe("/ddace/entities", 5, &Impl::onEntities, this);
    estop_sub_ = nh.subscribe("/ddace/estop", 5, &Impl::onEstop, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz_), &Impl::onTimer, this);
    ROS_INFO("path_follower: driving %zu robots at %.0f Hz (cruise %.3f m/s, lookahead %.3f m, arrival %.3f m)",
             robots_.size(), rate_hz_, gains_.cruise_speed_mps, gains_.lookahead_m, gains_.arrival_radius_m);
  }

 private:
  struct Robot {
    std::string name;
    ros::Publisher wheels, status;
    ros::Subscriber segment_sub;
    std::unique_ptr<exec::PathFollower> follower;  ///< null = no segment
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
      r.segment_id = m.segment_id;
      r.cycle = 0;
      publishStatus(r, m.segment_id, ddace::SegmentStatus::ACCEPTED, 0, 0, "");
    } catch (const std::exception& e) {
      ROS_ERROR("path_follower: %s: refusing segment %u: %s", r.name.c_str(), m.segment_id, e.what());
      publishStatus(r, m.segment_id, ddace::SegmentStatus::FAILED, 0, 0, e.what());
      publishWheels(r, 0, 0);
    }
  }

  void onEntities(const ddace::EntityArray& m) {
    const ros::Time now = ros::Time::now();
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
      r.stale_counting = false;
      const exec::FollowerOutput o = r.follower->compute(r.pose);
      publishWheels(r, o.wheels.left_mps, o.wheels.right_mps);
      if (o.done) {
        publishStatus(r, r.segment_id, ddace::SegmentStatus::DONE, 1.0, o.distance_to_goal_m, "");
        r.follower.reset();
      } else if (r.cycle++ % status_every_ == 0) {
        publishStatus(r, r.segment_id, ddace::SegmentStatus::RUNNING, o.progress, o.distance_to_goal_m, "");
      }
    }
  }

  std::map<std::string, std::unique_ptr<Robot>> robots_;
  exec::FollowerGains gains_;
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
