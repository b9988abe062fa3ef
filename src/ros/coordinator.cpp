// CoordinatorNode: see include/ddace/ros/coordinator.h.
#include "ddace/ros/coordinator.h"

#include <map>
#include <optional>
#include <sstream>

#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_srvs/Trigger.h>
#include <visualization_msgs/MarkerArray.h>

#include <ddace/CoordinatorState.h>
#include <ddace/Decision.h>
#include <ddace/DecisionRequest.h>
#include <ddace/EntityArray.h>
#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>

#include "exec_conversions.h"
#include "params.h"

namespace ddace::nodes {

class CoordinatorNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh) {
    spec_ = ros_exec::loadTaskSpec(rosparam::param<std::string>(pnh, "task", ""));
    exec::CoordinatorConfig cfg;
    cfg.decision_timeout_s = rosparam::param(pnh, "decision_timeout_s", cfg.decision_timeout_s);
    cfg.path_timeout_s = rosparam::param(pnh, "path_timeout_s", cfg.path_timeout_s);
    cfg.segment_timeout_s = rosparam::param(pnh, "segment_timeout_s", cfg.segment_timeout_s);
    cfg.segment_timeout_per_m_s = rosparam::param(pnh, "segment_timeout_per_m_s", cfg.segment_timeout_per_m_s);
    cfg.max_steps = rosparam::param(pnh, "max_steps", cfg.max_steps);
    try {
      coordinator_ = std::make_unique<exec::Coordinator>(spec_, cfg);
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + " (parameters under " + pnh.getNamespace() + ")");
    }
    const CoordinatorNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    arrival_radius_m_ = rosparam::param(pnh, "arrival_radius_m", spec_.arrival_radius);
    path_points_ = rosparam::param(pnh, "path_points", defaults.path_points);
    const double tick_hz = rosparam::param(pnh, "timeout_check_hz", defaults.timeout_check_hz);
    if (!(tick_hz > 0)) throw Error("parameter '" + pnh.resolveName("timeout_check_hz") + "' must be positive");
    autostart_ = rosparam::param(pnh, "autostart", defaults.autostart);
    resend_after_s_ = rosparam::param(pnh, "resend_after_s", defaults.resend_after_s);
    if (!(resend_after_s_ > 0)) throw Error("parameter '" + pnh.resolveName("resend_after_s") + "' must be positive");

    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto& e = spec_.entities[i];
      if (e.kind == task::EntityKind::Goal) continue;
      segment_pubs_[i] = nh.advertise<ddace::Segment>("/robots/" + e.name + "/segment", 10);
      status_subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
          "/robots/" + e.name + "/segment_status", 50,
          [this, i](const ddace::SegmentStatus::ConstPtr& m) { onStatus(static_cast<int>(i), *m); }));
    }
    decision_pub_ = nh.advertise<ddace::DecisionRequest>("/ddace/decision_request", 5);
    path_pub_ = nh.advertise<ddace::PathRequest>("/ddace/path_request", 50);
    estop_pub_ = nh.advertise<std_msgs::Bool>("/ddace/estop", 1, true);
    state_pub_ = pnh.advertise<ddace::CoordinatorState>("state", 1, true);
    marker_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("markers", 1, true);
    entities_sub_ = nh.subscribe("/ddace/entities", 5, &Impl::onEntities, this);
    decision_sub_ = nh.subscribe("/ddace/decision", 5, &Impl::onDecision, this);
    path_sub_ = nh.subscribe("/ddace/path", 50, &Impl::onPath, this);
    estop_sub_ = nh.subscribe("/ddace/estop", 5, &Impl::onEstopTopic, this);
    services_.push_back(pnh.advertiseService("start", &Impl::srvStart, this));
    services_.push_back(pnh.advertiseService("pause", &Impl::srvPause, this));
    services_.push_back(pnh.advertiseService("reset", &Impl::srvReset, this));
    services_.push_back(pnh.advertiseService("estop", &Impl::srvEstop, this));
    timer_ = nh.createTimer(ros::Duration(1.0 / tick_hz), &Impl::onTick, this);
    std_msgs::Bool released;
    released.data = false;
    estop_pub_.publish(released);
    publishState();
    ROS_INFO("coordinator: task '%s' with %zu entities; %s", spec_.name.c_str(), spec_.entities.size(),
             autostart_ ? "starts when every entity is tracked" : "call ~start to run");
  }

 private:
  static double now() { return ros::Time::now().toSec(); }

  void apply(const exec::CoordinatorOutput& out) {
    for (const auto& line : out.log) ROS_INFO("coordinator: %s", line.c_str());
    const ros::Time stamp = ros::Time::now();
    if (out.stop_all || out.state_changed) {
      // Whatever was asked before no longer needs an answer.
      if (coordinator_->state() != exec::RunState::Deciding) unanswered_decision_.reset();
      if (coordinator_->state() != exec::RunState::Planning) unanswered_paths_.clear();
      if (coordinator_->state() != exec::RunState::Executing) unanswered_segments_.clear();
    }
    // Stops first: a robot must never keep an old segment while a new one is planned.
    std::vector<int> stop = out.stop;
    if (out.stop_all)
      for (const auto& [i, pub] : segment_pubs_) stop.push_back(i);
    std::sort(stop.begin(), stop.end());
    stop.erase(std::unique(stop.begin(), stop.end()), stop.end());
    for (int i : stop) {
      ddace::Segment s;
      s.header.stamp = stamp;
      s.header.frame_id = frame_id_;
      s.mode = ddace::Segment::MODE_STOP;
      s.entity = spec_.entities[i].name;
      segment_pubs_[i].publish(s);
    }
    for (const auto& seg : out.segments) {
      ddace::Segment s;
      s.header.stamp = stamp;
      s.header.frame_id = frame_id_;
      s.mode = ddace::Segment::MODE_FOLLOW;
      s.entity = spec_.entities[seg.entity].name;
      s.segment_id = seg.segment_id;
      s.step = seg.step;
      s.token = ros_exec::toMsg(seg.token, spec_);
      ros_exec::toMsg(seg.path, frame_id_, stamp, s.path, s.progress, s.stddev_m);
      s.goal.x = seg.goal.x();
      s.goal.y = seg.goal.y();
      s.arrival_radius_m = arrival_radius_m_;
      s.timeout_s = seg.timeout_s;
      segment_pubs_[seg.entity].publish(s);
      unanswered_segments_[seg.segment_id] = {seg.entity, s, ros::WallTime::now()};
    }
    for (const auto& p : out.paths) {
      ddace::PathRequest r;
      r.header.stamp = stamp;
      r.header.frame_id = frame_id_;
      r.id = p.id;
      r.step = p.step;
      r.token = ros_exec::toMsg(p.token, spec_);
      r.start.x = p.start.x();
      r.start.y = p.start.y();
      r.goal.x = p.goal.x();
      r.goal.y = p.goal.y();
      r.points = path_points_;
      path_pub_.publish(r);
      unanswered_paths_[p.id] = {r, ros::WallTime::now()};
    }
    if (out.decision) {
      ddace::DecisionRequest r;
      r.header.stamp = stamp;
      r.header.frame_id = frame_id_;
      r.id = out.decision->id;
      r.step = out.decision->step;
      r.entity_names = spec_.entityNames();
      for (const auto& snap : out.decision->history) {
        ddace::Snapshot s;
        s.stamp = stamp;
        for (const auto& p : snap.positions) {
          geometry_msgs::Point pt;
          pt.x = p.x();
          pt.y = p.y();
          s.positions.push_back(pt);
        }
        r.history.push_back(s);
      }
      decision_pub_.publish(r);
      unanswered_decision_ = r;
      decision_sent_ = ros::WallTime::now();
    }
    if (out.state_changed || !out.segments.empty() || !out.stop.empty() || out.decision) publishState();
  }

  void onEntities(const ddace::EntityArray& m) {
    apply(coordinator_->onEntities(ros_exec::toObservation(m, spec_), now()));
    if (++entity_msgs_ % 5 == 0) publishMarkers();  // entity labels follow the robots
  }

  void onDecision(const ddace::Decision& m) {
    if (unanswered_decision_ && unanswered_decision_->id == m.id) unanswered_decision_.reset();
    if (!m.error.empty()) {
      apply(coordinator_->onDecisionError(m.id, "sequence_node: " + m.error, now()));
      return;
    }
    exec::Decision d;
    d.end = m.end;
    try {
      for (const auto& t : m.tokens) d.tokens.push_back(ros_exec::fromMsg(t, spec_));
    } catch (const Error& e) {
      apply(coordinator_->onDecisionError(m.id, std::string("/ddace/decision: ") + e.what(), now()));
      return;
    }
    apply(coordinator_->onDecision(m.id, d, now()));
  }

  void onPath(const ddace::PathResponse& m) {
    unanswered_paths_.erase(m.id);
    exec::PlannedPath p;
    std::string error = m.error;
    if (error.empty()) {
      try {
        p = ros_exec::fromMsg(m.path, m.stddev_m, "/ddace/path " + std::to_string(m.id));
      } catch (const Error& e) {
        error = e.what();
      }
    }
    if (m.fell_back) ROS_WARN("coordinator: path %u fell back to a default path (no learned primitive)", m.id);
    apply(coordinator_->onPath(m.id, p, error, now()));
  }

  void onStatus(int entity, const ddace::SegmentStatus& m) {
    unanswered_segments_.erase(m.segment_id);
    apply(coordinator_->onSegmentStatus(entity, m.segment_id, static_cast<exec::SegmentState>(m.status), m.progress,
                                        m.message, now()));
  }

  void onTick(const ros::TimerEvent&) {
    if (autostart_) {
      std::string missing;
      if (connected(missing)) {
        autostart_ = false;
        apply(coordinator_->start(now()));
      } else {
        ROS_INFO_THROTTLE(5.0, "coordinator: autostart waits for %s", missing.c_str());
      }
    }
    resendUnanswered();
    apply(coordinator_->onTick(now()));
  }

  /// At-least-once delivery: a request or segment nobody acknowledged within resend_after_s
  /// goes out again, unchanged (same id), e.g. when a node subscribed just too late. The
  /// receivers ignore an id they already handle; this never makes a new decision.
  void resendUnanswered() {
    const ros::WallTime now = ros::WallTime::now();
    auto due = [&](ros::WallTime& sent) {
      if ((now - sent).toSec() < resend_after_s_) return false;
      sent = now;
      return true;
    };
    if (unanswered_decision_ && due(decision_sent_)) {
      ROS_WARN("coordinator: decision request %u unanswered for %.1f s, sending it again", unanswered_decision_->id,
               resend_after_s_);
      decision_pub_.publish(*unanswered_decision_);
    }
    for (auto& [id, p] : unanswered_paths_)
      if (due(p.sent)) {
        ROS_WARN("coordinator: path request %u unanswered, sending it again", id);
        path_pub_.publish(p.msg);
      }
    for (auto& [id, seg] : unanswered_segments_)
      if (due(seg.sent)) {
        ROS_WARN("coordinator: segment %u of %s not acknowledged, sending it again", id, seg.msg.entity.c_str());
        segment_pubs_[seg.entity].publish(seg.msg);
      }
  }

  /// Every collaborator is subscribed: a request published now is not lost.
  bool connected(std::string& missing) const {
    if (decision_pub_.getNumSubscribers() == 0) missing = "a sequence node on /ddace/decision_request";
    else if (path_pub_.getNumSubscribers() == 0) missing = "a path node on /ddace/path_request";
    for (const auto& [i, pub] : segment_pubs_)
      if (missing.empty() && pub.getNumSubscribers() == 0) missing = "an executor on " + pub.getTopic();
    return missing.empty();
  }

  void onEstopTopic(const std_msgs::Bool& m) {
    if (m.data && coordinator_->state() != exec::RunState::EStopped)
      apply(coordinator_->emergencyStop(now(), "e-stop on /ddace/estop"));
  }

  bool srvStart(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    std::string missing;
    if (!connected(missing)) {
      res.success = false;
      res.message = "not started: no " + missing;
      return true;
    }
    return answer(coordinator_->start(now()), res,
                  {exec::RunState::WaitingForEntities, exec::RunState::Deciding, exec::RunState::Planning,
                   exec::RunState::Executing});
  }
  bool srvPause(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    return answer(coordinator_->pause(now()), res, {exec::RunState::Paused});
  }
  bool srvReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    std_msgs::Bool released;
    released.data = false;
    estop_pub_.publish(released);
    return answer(coordinator_->reset(now()), res, {exec::RunState::Idle});
  }
  bool srvEstop(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    std_msgs::Bool stop;
    stop.data = true;
    estop_pub_.publish(stop);  // the followers zero every wheel on receipt
    return answer(coordinator_->emergencyStop(now(), "~estop service"), res, {exec::RunState::EStopped});
  }

  bool answer(const exec::CoordinatorOutput& out, std_srvs::Trigger::Response& res,
              std::initializer_list<exec::RunState> ok) {
    apply(out);
    res.success = std::find(ok.begin(), ok.end(), coordinator_->state()) != ok.end();
    std::ostringstream os;
    os << "state " << exec::toString(coordinator_->state());
    if (!out.log.empty()) os << ": " << out.log.back();
    res.message = os.str();
    return true;
  }

  void publishState() {
    ddace::CoordinatorState s;
    s.header.stamp = ros::Time::now();
    s.header.frame_id = frame_id_;
    s.state = static_cast<uint8_t>(coordinator_->state());
    s.state_name = exec::toString(coordinator_->state());
    s.reason = coordinator_->reason();
    for (const auto& step : coordinator_->steps()) {
      ddace::Step m;
      m.index = step.step;
      for (const auto& t : step.tokens) {
        m.tokens.push_back(ros_exec::toMsg(t.token, spec_));
        m.status.push_back(static_cast<uint8_t>(t.state));
        m.progress.push_back(t.progress);
      }
      m.decided = ros::Time(step.decided_s);
      if (step.finished_s >= 0) m.finished = ros::Time(step.finished_s);
      s.steps.push_back(m);
    }
    for (int e : coordinator_->activeEntities()) s.active.push_back(spec_.entities[e].name);
    s.decisions_requested = coordinator_->decisionsRequested();
    const auto met = coordinator_->goalConditionsMet();
    for (size_t i = 0; i < spec_.goal_conditions.size(); ++i) {
      const auto& gc = spec_.goal_conditions[i];
      std::ostringstream os;
      os << gc.entity << " at " << gc.at << " (" << gc.tolerance << " m)";
      s.goal_conditions.push_back(os.str());
      s.goal_conditions_met.push_back(met[i]);
    }
    state_pub_.publish(s);
    publishMarkers();
  }

  void publishMarkers() {
    if (marker_pub_.getNumSubscribers() == 0) return;
    using visualization_msgs::Marker;
    visualization_msgs::MarkerArray arr;
    Marker clear;
    clear.action = Marker::DELETEALL;
    arr.markers.push_back(clear);
    const ros::Time stamp = ros::Time::now();
    int id = 0;
    auto base = [&](const std::string& ns, int type) {
      Marker m;
      m.header.frame_id = frame_id_;
      m.header.stamp = stamp;
      m.ns = ns;
      m.id = id++;
      m.type = type;
      m.action = Marker::ADD;
      m.pose.orientation.w = 1;
      return m;
    };
    auto point = [](const Eigen::Vector2d& p, double z = 0.0) {
      geometry_msgs::Point q;
      q.x = p.x();
      q.y = p.y();
      q.z = z;
      return q;
    };
    const auto& obs = coordinator_->observation();
    // Entity labels.
    for (size_t i = 0; i < obs.positions.size(); ++i) {
      Marker t = base("labels", Marker::TEXT_VIEW_FACING);
      t.pose.position = point(obs.positions[i], 0.04);
      t.scale.z = 0.03;
      t.color.r = t.color.g = t.color.b = 1.0;
      t.color.a = obs.tracked[i] ? 1.0 : 0.4;
      t.text = spec_.entities[i].name + (obs.tracked[i] ? "" : " (lost)");
      arr.markers.push_back(t);
    }
    if (!coordinator_->steps().empty()) {
      const auto& step = coordinator_->steps().back();
      std::ostringstream os;
      os << "step " << step.step + 1 << " [" << exec::toString(coordinator_->state()) << "]:";
      for (const auto& tr : step.tokens) {
        os << " " << task::tokenKey(tr.token, spec_);
        if (tr.path.points.size() < 2) continue;
        // The planned path ...
        Marker line = base("paths", Marker::LINE_STRIP);
        line.scale.x = 0.004;
        const bool done = tr.state == exec::SegmentState::Done;
        line.color.r = done ? 0.4f : 0.1f;
        line.color.g = done ? 0.4f : 0.6f;
        line.color.b = done ? 0.4f : 1.0f;
        line.color.a = 1.0;
        for (const auto& p : tr.path.points) line.points.push_back(point(p, 0.002));
        arr.markers.push_back(line);
        // ... its +-2 sigma band (normal to the path, as a triangle strip) ...
        Marker band = base("band_2sigma", Marker::TRIANGLE_LIST);
        band.scale.x = band.scale.y = band.scale.z = 1.0;
        band.color = line.color;
        band.color.a = 0.25;
        const auto& pts = tr.path.points;
        auto offset = [&](size_t k, double sign) {
          const Eigen::Vector2d d = (k + 1 < pts.size() ? pts[k + 1] - pts[k] : pts[k] - pts[k - 1]).normalized();
          const double sd = k < tr.path.stddev_m.size() ? tr.path.stddev_m[k] : 0.0;
          return Eigen::Vector2d(pts[k] + sign * 2 * sd * Eigen::Vector2d(-d.y(), d.x()));
        };
        for (size_t k = 0; k + 1 < pts.size(); ++k) {
          const auto a = offset(k, 1), b = offset(k, -1), c = offset(k + 1, 1), d = offset(k + 1, -1);
          for (const auto& p : {a, b, c, c, b, d}) band.points.push_back(point(p, 0.001));
        }
        if (!band.points.empty()) arr.markers.push_back(band);
        // ... and its goal.
        Marker goal = base("goals", Marker::CYLINDER);
        goal.pose.position = point(tr.goal, 0.001);
        goal.scale.x = goal.scale.y = 2 * arrival_radius_m_;
        goal.scale.z = 0.002;
        goal.color = line.color;
        goal.color.a = 0.5;
        arr.markers.push_back(goal);
      }
      Marker text = base("current_step", Marker::TEXT_VIEW_FACING);
      text.pose.position.x = 0.5;
      text.pose.position.y = 1.05;
      text.pose.position.z = 0.05;
      text.scale.z = 0.035;
      text.color.r = text.color.g = 1.0;
      text.color.b = 0.6f;
      text.color.a = 1.0;
      text.text = os.str();
      arr.markers.push_back(text);
    }
    marker_pub_.publish(arr);
  }

  struct SentPath {
    ddace::PathRequest msg;
    ros::WallTime sent;
  };
  struct SentSegment {
    int entity;
    ddace::Segment msg;
    ros::WallTime sent;
  };
  std::optional<ddace::DecisionRequest> unanswered_decision_;
  ros::WallTime decision_sent_;
  std::map<uint32_t, SentPath> unanswered_paths_;
  std::map<uint32_t, SentSegment> unanswered_segments_;
  double resend_after_s_ = 0;  // set from the parameters

  ros::NodeHandle nh_;
  task::TaskSpec spec_;
  std::unique_ptr<exec::Coordinator> coordinator_;
  std::string frame_id_;
  double arrival_radius_m_ = task::kDefaultArrivalRadius;
  int path_points_ = 0;
  bool autostart_ = false;
  long entity_msgs_ = 0;
  std::map<int, ros::Publisher> segment_pubs_;
  std::vector<ros::Subscriber> status_subs_;
  ros::Publisher decision_pub_, path_pub_, estop_pub_, state_pub_, marker_pub_;
  ros::Subscriber entities_sub_, decision_sub_, path_sub_, estop_sub_;
  std::vector<ros::ServiceServer> services_;
  ros::Timer timer_;
};

CoordinatorNode::CoordinatorNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

CoordinatorNode::~CoordinatorNode() = default;

}  // namespace ddace::nodes
