// CoordinatorNode: see include/ddace/ros/coordinator.h.
#include "ddace/ros/coordinator.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <optional>
#include <sstream>

#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_srvs/Trigger.h>
#include <visualization_msgs/MarkerArray.h>

#include <ddace/ActiveSegment.h>
#include <ddace/CoordinatorState.h>
#include <ddace/Decision.h>
#include <ddace/DecisionRequest.h>
#include <ddace/EntityArray.h>
#include <ddace/Heartbeat.h>
#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "exec_conversions.h"
#include "launched_nodes.h"
#include "params.h"
#include "ddace/exec/liveness.h"
#include "ddace/exec/outbox.h"
#include "ddace/exec/path_band.h"
#include "ddace/gp/primitives.h"
#include "ddace/graph/dependencies.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/ros/path_follower.h"
#include "ddace/task/end_point.h"
#include "ddace/task/task_dir.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::nodes {
namespace {
const char* const kFollower = "/path_follower";  ///< the follower role's default node
}  // namespace

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
    cfg.arrival_radius_m = rosparam::param(pnh, "arrival_radius_m", spec_.arrival_radius);
    cfg.arrival_tolerance_m = rosparam::param(pnh, "arrival_tolerance_m", cfg.arrival_tolerance_m);
    cfg.max_replans = rosparam::param(pnh, "max_replans", cfg.max_replans);
    cfg.robot_lost_after_s = rosparam::param(pnh, "robot_lost_after_s", cfg.robot_lost_after_s);
    cfg.loads_ride = followerLoadsRide(pnh);
    cfg.dispatch = exec::parseDispatchMode(rosparam::param<std::string>(pnh, "dispatch", exec::toString(cfg.dispatch)),
                                           "parameter '" + pnh.resolveName("dispatch") + "'");
    try {
      const DispatchInputs dispatch = loadDispatchInputs(pnh, cfg);
      // Ids past every id of a coordinator this one replaces (exec::firstIdAt).
      coordinator_ = std::make_unique<exec::Coordinator>(spec_, cfg, loadEndPoints(pnh),
                                                         exec::firstIdAt(ros::WallTime::now().toSec()),
                                                         dispatch.dependencies, dispatch.policy_reads_scene);
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + " (parameters under " + pnh.getNamespace() + ")");
    }
    const CoordinatorNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    arrival_radius_m_ = cfg.arrival_radius_m;
    // The executor stops inside the radius a DONE is checked against (task/end_point.h).
    stop_radius_m_ = task::stopRadius(cfg.arrival_radius_m, cfg.arrival_tolerance_m);
    path_points_ = rosparam::param(pnh, "path_points", defaults.path_points);
    const double tick_hz = rosparam::param(pnh, "timeout_check_hz", defaults.timeout_check_hz);
    if (!(tick_hz > 0)) throw Error("parameter '" + pnh.resolveName("timeout_check_hz") + "' must be positive");
    autostart_ = rosparam::param(pnh, "autostart", defaults.autostart);
    start_timeout_s_ = rosparam::param(pnh, "start_timeout_s", defaults.start_timeout_s);
    if (!(start_timeout_s_ >= 0))
      throw Error("parameter '" + pnh.resolveName("start_timeout_s") + "' must be 0 (wait on) or positive");
    autostart_deadline_ = ros::WallTime::now() + ros::WallDuration(start_timeout_s_);
    const double resend_after_s = rosparam::param(pnh, "resend_after_s", defaults.resend_after_s);
    if (!(resend_after_s > 0)) throw Error("parameter '" + pnh.resolveName("resend_after_s") + "' must be positive");
    outbox_ = std::make_unique<exec::Outbox>(resend_after_s);
    const double state_hz = rosparam::param(pnh, "state_rate_hz", defaults.state_rate_hz);
    if (!(state_hz > 0)) throw Error("parameter '" + pnh.resolveName("state_rate_hz") + "' must be positive");
    const double liveness_hz = rosparam::param(pnh, "liveness_check_hz", defaults.liveness_check_hz);
    if (!(liveness_hz > 0)) throw Error("parameter '" + pnh.resolveName("liveness_check_hz") + "' must be positive");

    loadRoles(pnh);
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto& e = spec_.entities[i];
      if (e.kind == task::EntityKind::Goal) continue;
      segment_pubs_[i] = advertiseWatched<ddace::Segment>(nh, "/robots/" + e.name + "/segment", 10);
      status_subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
          "/robots/" + e.name + "/segment_status", 50,
          [this, i](const ddace::SegmentStatus::ConstPtr& m) { onStatus(static_cast<int>(i), *m); }));
      if (e.kind != task::EntityKind::Robot) continue;
      // Only the coordinator can stop a robot whose follower died: it publishes zeros itself.
      wheel_pubs_[i] = advertiseWatched<ddace::WheelCommand>(nh, "/robots/" + e.name + "/wheels", 10);
      const size_t role = follower_role_.at(i);
      wheel_subs_.push_back(
          nh.subscribe<ddace::WheelCommand>("/robots/" + e.name + "/wheels", 20,
                                            boost::function<void(const ros::MessageEvent<const ddace::WheelCommand>&)>(
                                                [this, role](const ros::MessageEvent<const ddace::WheelCommand>& ev) {
                                                  if (ev.getPublisherName() == roles_.node(role))
                                                    roles_.heartbeat(role, steadyNow());
                                                })));
    }
    decision_pub_ = advertiseWatched<ddace::DecisionRequest>(nh, "/ddace/decision_request", 5);
    path_pub_ = advertiseWatched<ddace::PathRequest>(nh, "/ddace/path_request", 50);
    estop_pub_ = nh.advertise<std_msgs::Bool>("/ddace/estop", 1, true);
    // The recorder's link on ~state is its presence: a monitor killed mid-run stops the run.
    state_pub_ = advertiseWatched<ddace::CoordinatorState>(pnh, "state", 1, true);
    for (const auto& [role, node] : heartbeat_roles_)
      heartbeat_subs_.push_back(nh.subscribe<ddace::Heartbeat>(
          node + "/heartbeat", 5,
          boost::function<void(const ros::MessageEvent<const ddace::Heartbeat>&)>(
              [this, role = role](const ros::MessageEvent<const ddace::Heartbeat>& ev) { onHeartbeat(role, ev); })));
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
    state_timer_ = nh.createTimer(ros::Duration(1.0 / state_hz), [this](const ros::TimerEvent&) { publishState(); });
    liveness_timer_ =
        nh.createTimer(ros::Duration(1.0 / liveness_hz), [this](const ros::TimerEvent&) { checkRoles(); });
    std_msgs::Bool released;
    released.data = false;
    estop_pub_.publish(released);
    publishState();
    ROS_INFO("coordinator: task '%s' with %zu entities; %s", spec_.name.c_str(), spec_.entities.size(),
             autostart_ ? "starts when every entity is tracked" : "call ~start to run");
  }

 private:
  /// Where motions end (task/end_point.h): the model's learned end points (~model, a model
  /// directory), else learned from the demonstrations of ~train (a task directory: the
  /// replay's; default ~task), else the footprints' defaults (a task.yaml alone).
  task::EndPointModel loadEndPoints(ros::NodeHandle& pnh) const {
    namespace fs = std::filesystem;
    rosparam::alsoReads(pnh, {"train"});  // read only without ~model
    const std::string model = rosparam::param<std::string>(pnh, "model", "");
    if (!model.empty()) {
      ros_exec::requireAbsolute(model, pnh.resolveName("model"));
      const std::string file = (fs::path(model) / gp::kPrimitivesFile).string();
      const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::load(file);
      if (lib.entityNames() == spec_.entityNames()) return lib.endPoints();
      // The same kinds in other numbers (the sequence node checks the model can run on them).
      try {
        return lib.boundTo(spec_).endPoints();
      } catch (const Error& e) {
        throw Error(Diagnostic{
            file, 0, 0,
            "the model's entities are not the task's (parameter '" + pnh.resolveName("model") + "'): " + e.what()});
      }
    }
    std::string train = rosparam::param<std::string>(pnh, "train", "");
    if (train.empty()) train = rosparam::param<std::string>(pnh, "task", "");
    if (!train.empty() && fs::is_directory(fs::path(train) / "demos")) {
      ros_exec::requireAbsolute(train, pnh.resolveName("train"));
      return task::learnEndPoints(spec_, task::loadTaskDir(train).demos);
    }
    return {};
  }

  /// Whom each token waits for and whether a decision reads the scene (exec/dispatch.h; a
  /// recovery re-decides a step only then, CoordinatorConfig::max_replans): the model's
  /// manifest (~model), else a replay's (~train's demonstrations, replayed in a fixed order).
  /// Steps dispatch without recovery needs neither: every token waits for every earlier one.
  struct DispatchInputs {
    graph::Dependencies dependencies;
    bool policy_reads_scene = true;
  };
  DispatchInputs loadDispatchInputs(ros::NodeHandle& pnh, const exec::CoordinatorConfig& cfg) const {
    DispatchInputs in;
    const bool async = cfg.dispatch == exec::DispatchMode::Async;
    if (!async && cfg.max_replans == 0) return in;
    const std::string model = rosparam::param<std::string>(pnh, "model", "");
    if (!model.empty()) {
      const tgn::SequenceModel m = tgn::SequenceModel::load(model);
      if (async) in.dependencies = m.info().dependencies;
      in.policy_reads_scene = pipeline::policyReadsScene(m.info());
    } else {
      in.policy_reads_scene = false;  // a replay: the demonstration's steps in their order
      if (!async) return in;
      std::string train = rosparam::param<std::string>(pnh, "train", "");
      if (train.empty()) train = rosparam::param<std::string>(pnh, "task", "");
      if (!std::filesystem::is_directory(std::filesystem::path(train) / "demos"))
        throw Error("parameter '" + pnh.resolveName("dispatch") +
                    "' is async but there is neither ~model nor ~train demonstrations to learn what each token "
                    "waits for");
      in.dependencies = graph::learnDependencies(spec_, task::loadTaskDir(train).demos);
    }
    if (async)
      ROS_INFO("coordinator: async dispatch, %s; decisions %s",
               in.dependencies.learned
                   ? "learned dependencies"
                   : "a model without learned dependencies (every token waits for every earlier one)",
               in.policy_reads_scene ? "once every entity has settled (the policy reads the scene)"
                                     : "ahead (a fixed order)");
    if (cfg.max_replans > 0)
      ROS_INFO("coordinator: up to %d recoveries per token and step: %s", cfg.max_replans,
               in.policy_reads_scene ? "a step is re-decided from the scene as it is"
                                     : "a token is re-planned from where it is (a fixed order)");
    return in;
  }

  static double now() { return ros::Time::now().toSec(); }
  /// The liveness clock: monotonic, so a step of the system clock is nobody's silence.
  static double steadyNow() { return ros::SteadyTime::now().toSec(); }

  /// ~heartbeat of a role's node: counts only from that node; a problem it reports loses the role.
  void onHeartbeat(size_t role, const ros::MessageEvent<const ddace::Heartbeat>& ev) {
    if (ev.getPublisherName() != roles_.node(role)) return;
    roles_.heartbeat(role, steadyNow());
    roles_.fault(role, ev.getConstMessage()->problem);
  }

  void apply(const exec::CoordinatorOutput& out) {
    for (const auto& line : out.log) ROS_INFO("coordinator: %s", line.c_str());
    const ros::Time stamp = ros::Time::now();
    forgetAnswered();
    // Stops first: a robot must never keep an old segment while a new one is planned.
    std::vector<int> stop = out.stop;
    if (out.stop_all)
      for (const auto& [i, pub] : segment_pubs_) stop.push_back(i);
    std::sort(stop.begin(), stop.end());
    stop.erase(std::unique(stop.begin(), stop.end()), stop.end());
    // Zero wheels from here, now: the follower zeroes only when the STOP reaches it (a
    // cycle of its own may still be under way), and it may be the node that died.
    ddace::WheelCommand zero;
    zero.header.stamp = stamp;
    for (int i : stop)
      if (auto w = wheel_pubs_.find(i); w != wheel_pubs_.end()) w->second.publish(zero);
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
      s.arrival_radius_m = stop_radius_m_;
      s.timeout_s = seg.timeout_s;
      segment_pubs_[seg.entity].publish(s);
      sent_segments_[seg.segment_id] = {seg.entity, s};
      outbox_->sent(exec::Outbox::Kind::Segment, seg.segment_id, wallNow());
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
      sent_paths_[p.id] = r;
      outbox_->sent(exec::Outbox::Kind::Path, p.id, wallNow());
    }
    if (out.decision) {
      ddace::DecisionRequest r;
      r.header.stamp = stamp;
      r.header.frame_id = frame_id_;
      r.id = out.decision->id;
      r.step = out.decision->step;
      r.entity_names = spec_.entityNames();
      for (int e : out.decision->lost) r.lost.push_back(spec_.entities[static_cast<size_t>(e)].name);
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
      sent_decisions_[r.id] = r;
      outbox_->sent(exec::Outbox::Kind::Decision, r.id, wallNow());
    }
    if (out.state_changed || !out.segments.empty() || !out.stop.empty() || out.decision) publishState();
  }

  /// Whatever the run no longer awaits (a decision made, a path in, a segment ended or
  /// cancelled) is not sent again.
  void forgetAnswered() {
    std::set<uint32_t> paths, segments;
    for (const auto& step : coordinator_->steps())
      for (const auto& t : step.tokens) {
        if (t.path_request != 0) paths.insert(t.path_request);
        if (t.segment_id != 0 && t.state != exec::SegmentState::Done && t.state != exec::SegmentState::Failed &&
            t.state != exec::SegmentState::Aborted)
          segments.insert(t.segment_id);
      }
    const uint32_t decision = coordinator_->pendingDecision();
    using K = exec::Outbox::Kind;
    const auto prune = [this](auto& sent, K kind, const auto& awaited) {
      for (auto it = sent.begin(); it != sent.end();)
        if (awaited(it->first)) {
          ++it;
        } else {
          outbox_->acknowledged(kind, it->first);
          it = sent.erase(it);
        }
    };
    prune(sent_decisions_, K::Decision, [&](uint32_t id) { return id == decision; });
    prune(sent_paths_, K::Path, [&](uint32_t id) { return paths.count(id) != 0; });
    prune(sent_segments_, K::Segment, [&](uint32_t id) { return segments.count(id) != 0; });
  }

  void onEntities(const ros::MessageEvent<const ddace::EntityArray>& ev) {
    const ddace::EntityArray& m = *ev.getConstMessage();
    if (pose_role_ && ev.getPublisherName() == roles_.node(*pose_role_)) roles_.heartbeat(*pose_role_, steadyNow());
    apply(coordinator_->onEntities(ros_exec::toObservation(m, spec_), now()));
    if (++entity_msgs_ % 5 == 0) publishMarkers();  // entity labels follow the robots
  }

  void onDecision(const ddace::Decision& m) {
    outbox_->acknowledged(exec::Outbox::Kind::Decision, m.id);
    if (!m.error.empty()) {
      apply(coordinator_->onDecisionError(m.id, "sequence_node: " + m.error, now()));
      return;
    }
    exec::Decision d;
    d.end = m.end;
    exec::DecisionProbabilities prob;
    prob.end = m.end_probability;
    try {
      for (const auto& t : m.tokens) {
        d.tokens.push_back(ros_exec::fromMsg(t, spec_));
        prob.tokens.push_back(t.probability);
      }
    } catch (const Error& e) {
      apply(coordinator_->onDecisionError(m.id, std::string("/ddace/decision: ") + e.what(), now()));
      return;
    }
    apply(coordinator_->onDecision(m.id, d, now(), prob));
  }

  void onPath(const ddace::PathResponse& m) {
    outbox_->acknowledged(exec::Outbox::Kind::Path, m.id);
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
    if (m.entity == spec_.entities[entity].name) outbox_->acknowledged(exec::Outbox::Kind::Segment, m.segment_id);
    exec::StatusReport r;
    r.topic_entity = entity;
    r.entity = m.entity;
    r.segment_id = m.segment_id;
    r.code = m.status;
    r.progress = m.progress;
    r.distance_to_goal_m = m.distance_to_goal_m;
    r.message = m.message;
    const exec::CoordinatorOutput out = coordinator_->onSegmentStatus(r, now());
    for (const auto& line : out.log)
      if (line.rfind("ignoring", 0) == 0) ROS_WARN("coordinator: %s", line.c_str());
    exec::CoordinatorOutput rest = out;
    rest.log.erase(std::remove_if(rest.log.begin(), rest.log.end(),
                                  [](const std::string& l) { return l.rfind("ignoring", 0) == 0; }),
                   rest.log.end());
    apply(rest);
  }

  void onTick(const ros::TimerEvent&) {
    if (coordinator_->state() == exec::RunState::Idle) abortIfARoleEnded();
    // Autostart tries at most 5 times a second (the recorder's check asks every publisher).
    if (autostart_ && ros::WallTime::now() >= next_autostart_try_) {
      next_autostart_try_ = ros::WallTime::now() + ros::WallDuration(0.2);
      std::string missing;
      if (connected(missing)) {
        autostart_ = false;
        apply(coordinator_->start(now()));
      } else if (start_timeout_s_ > 0 && ros::WallTime::now() >= autostart_deadline_) {
        // A node that died at startup would otherwise leave the launch waiting for ever.
        autostart_ = false;
        ROS_ERROR("coordinator: autostart gave up after start_timeout_s = %g s; waiting for: %s", start_timeout_s_,
                  missing.c_str());
        std::ostringstream why;
        why << "not started within start_timeout_s = " << start_timeout_s_ << " s; waiting for: " << missing;
        apply(coordinator_->abortStart(why.str(), now()));
      } else {
        ROS_INFO_THROTTLE(5.0, "coordinator: autostart waits for: %s", missing.c_str());
      }
    }
    resendUnanswered();
    apply(coordinator_->onTick(now()));
  }

  /// A role's node that ended before the run started (as roslaunch tells: a node never
  /// connected leaves no link to see drop) means the run can never start: it is aborted at
  /// once naming the node, and the monitor ends the launch. Asked once a second.
  void abortIfARoleEnded() {
    if (ros::WallTime::now() < next_ended_check_) return;
    next_ended_check_ = ros::WallTime::now() + ros::WallDuration(1.0);
    std::vector<std::string> nodes;
    for (size_t k = 0; k < roles_.size(); ++k) nodes.push_back(roles_.node(k));
    std::string why;
    for (const auto& [node, process] : ros_launch::endedNodes(nodes))
      why += (why.empty() ? "" : "; ") + ("node " + node + " is not running: it exited before the run started (" +
                                          process + " in roslaunch's output says why)");
    ended_before_start_ = why;
    if (why.empty()) return;
    std::string missing;
    if (!connected(missing)) why += "; waiting for: " + missing;
    ROS_ERROR("coordinator: %s: the run cannot start", why.c_str());
    autostart_ = false;
    apply(coordinator_->abortStart(why, now()));
  }

  static double wallNow() { return ros::WallTime::now().toSec(); }

  /// At-least-once delivery (exec::Outbox): what nobody acknowledged goes out again, same id.
  void resendUnanswered() {
    using K = exec::Outbox::Kind;
    for (const auto& [kind, id] : outbox_->due(wallNow())) {
      if (kind == K::Decision && sent_decisions_.count(id)) {
        ROS_WARN("coordinator: decision request %u unanswered for %.1f s, sending it again", id,
                 outbox_->resendAfter());
        decision_pub_.publish(sent_decisions_[id]);
      } else if (kind == K::Path && sent_paths_.count(id)) {
        ROS_WARN("coordinator: path request %u unanswered, sending it again", id);
        path_pub_.publish(sent_paths_[id]);
      } else if (kind == K::Segment && sent_segments_.count(id)) {
        const auto& seg = sent_segments_[id];
        ROS_WARN("coordinator: segment %u of %s not acknowledged, sending it again", id, seg.msg.entity.c_str());
        segment_pubs_[seg.entity].publish(seg.msg);
      }
    }
  }

  /// The node of every role, from ~roles (config/execution.yaml). An empty name leaves the
  /// role unwatched (e.g. objects nobody moves on the real table).
  /// The node of role `key` (under ~roles), absolute ("" = none).
  static std::string roleNode(const ros::NodeHandle& pnh, const std::string& key, const std::string& fallback) {
    std::string n = rosparam::param<std::string>(ros::NodeHandle(pnh, "roles"), key, fallback);
    if (!n.empty() && n[0] != '/') n = "/" + n;
    return n;
  }

  /// Whether loads ride in front of their carriers or are pushed: the follower's own
  /// ~loads_ride, which decides whether its carriers back off (a pushing carrier is judged
  /// where it then stands).
  static bool followerLoadsRide(const ros::NodeHandle& pnh) {
    const bool fallback = PathFollowerNode::Params{}.loads_ride;
    const std::string follower = roleNode(pnh, "follower", kFollower);
    return follower.empty() ? fallback : rosparam::param(ros::NodeHandle(follower), "loads_ride", fallback);
  }

  void loadRoles(const ros::NodeHandle& pnh) {
    const ros::NodeHandle r(pnh, "roles");
    auto name = [&](const std::string& key, const std::string& fallback) { return roleNode(pnh, key, fallback); };
    const CoordinatorNode::Params defaults;
    const double heartbeat_s = rosparam::param(r, "heartbeat_timeout_s", defaults.heartbeat_timeout_s);
    const double pose_s = rosparam::param(r, "pose_timeout_s", defaults.pose_timeout_s);
    // 0: presence only (a test that plays the nodes itself).
    if (!(heartbeat_s >= 0)) throw Error("parameter '" + r.resolveName("heartbeat_timeout_s") + "' must be >= 0");
    if (!(pose_s >= 0)) throw Error("parameter '" + r.resolveName("pose_timeout_s") + "' must be >= 0");
    // A node serving requests: present while subscribed to them, alive while its ~heartbeat comes.
    auto serving = [&](const std::string& role, const std::string& node, const std::string& topic) {
      const size_t k = roles_.add(role, node, "subscribed to " + topic, heartbeat_s);
      watched_.push_back({k, topic, node});
      heartbeat_roles_.emplace_back(k, node);
    };
    const std::string seq = name("sequence", "/sequence"), paths = name("paths", "/gp_path");
    if (!seq.empty()) serving("sequence node", seq, "/ddace/decision_request");
    if (!paths.empty()) serving("path node", paths, "/ddace/path_request");
    const std::string follower = name("follower", kFollower), objects = name("object_executor", "/mock_robots");
    const std::string driver = name("driver", "/mock_robots");
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto& e = spec_.entities[i];
      const std::string topic = "/robots/" + e.name + "/segment";
      if (e.kind == task::EntityKind::Robot) {
        const std::string node = name("followers/" + e.name, follower);
        if (node.empty())
          throw Error("parameter '" + r.resolveName("follower") + "' is empty: every robot needs a follower");
        follower_role_[i] = roles_.add("follower of " + e.name, node, "subscribed to " + topic, heartbeat_s);
        watched_.push_back({follower_role_[i], topic, node});
        // The node that moves the robot (mock robots, the radio bridge): its link drops at once.
        const std::string wheels = "/robots/" + e.name + "/wheels", driver_node = name("drivers/" + e.name, driver);
        if (!driver_node.empty())
          watched_.push_back(
              {roles_.add("driver of " + e.name, driver_node, "subscribed to " + wheels), wheels, driver_node});
      } else if (e.kind == task::EntityKind::Object && !objects.empty()) {
        watched_.push_back({roles_.add("executor of " + e.name, objects, "subscribed to " + topic), topic, objects});
      }
    }
    recorder_ = name("recorder", "");
    if (!recorder_.empty()) serving("recorder", recorder_, pnh.resolveName("state"));
    const std::string pose = name("pose_source", "/mock_robots");
    if (!pose.empty()) pose_role_ = roles_.add("pose source", pose, "publishing /ddace/entities", pose_s);
  }

  /// Advertises `topic` and keeps track of which nodes are subscribed to it (roscpp calls
  /// the disconnect callback as soon as a subscriber's connection drops, e.g. it was killed).
  template <typename M>
  ros::Publisher advertiseWatched(ros::NodeHandle& nh, const std::string& name, uint32_t queue, bool latch = false) {
    const std::string topic = nh.resolveName(name);
    auto connect = [this, topic](const ros::SingleSubscriberPublisher& p) {
      std::lock_guard<std::mutex> l(links_mutex_);
      links_.insert({topic, p.getSubscriberName()});
    };
    auto disconnect = [this, topic](const ros::SingleSubscriberPublisher& p) {
      {
        std::lock_guard<std::mutex> l(links_mutex_);
        auto it = links_.find({topic, p.getSubscriberName()});
        if (it != links_.end()) links_.erase(it);
      }
      // A dropped link is the first sign of a dead node: act on it now, not at the next check.
      checkRoles();
    };
    return nh.advertise<M>(topic, queue, connect, disconnect, ros::VoidConstPtr(), latch);
  }

  /// Whether each role's node is connected on its topic.
  void updatePresence() {
    {
      std::lock_guard<std::mutex> l(links_mutex_);
      for (const auto& w : watched_) roles_.present(w.role, links_.count({w.topic, w.node}) != 0);
    }
    // The pose source publishes to us: present while its messages come (heartbeat rule).
    if (pose_role_) roles_.present(*pose_role_, entities_sub_.getNumPublishers() > 0);
  }

  /// Runs on the spinner thread: roscpp queues the (dis)connect callbacks like messages.
  void checkRoles() {
    updatePresence();
    if (!coordinator_->running()) {
      if (roles_.armed())
        ROS_INFO("coordinator: longest heartbeat silences of the run: %s", roles_.longestSilences().c_str());
      roles_.disarm();
      return;
    }
    if (!roles_.armed()) roles_.arm(steadyNow());
    if (const auto lost = roles_.check(steadyNow())) {
      ROS_ERROR("coordinator: %s: stopping every robot", lost->c_str());
      apply(coordinator_->abortRun(*lost, now()));  // stop_all: zero wheels first
    }
  }

  /// Every role is served by its node (a request published now is not lost) and, for a
  /// new run, the recorder records every topic (the record starts with the run).
  /// `missing` says what is not there yet.
  bool connected(std::string& missing) {
    updatePresence();
    const auto m = roles_.missing(steadyNow());
    missing.clear();
    for (const auto& r : m) missing += (missing.empty() ? "" : ", ") + r;
    return m.empty() && recorderReady(missing);
  }

  /// The recorder's `~ready` (std_srvs/Trigger): it checks that every publisher of every
  /// recorded topic is connected to it. Asked only before a new run: only then is it
  /// worth blocking this thread (no robot is driven in Idle).
  bool recorderReady(std::string& missing) {
    if (recorder_.empty() || coordinator_->state() != exec::RunState::Idle) return true;
    const std::string service = recorder_ + "/ready";
    std_srvs::Trigger t;
    if (!ros::service::exists(service, false)) {
      missing = "the recorder " + recorder_ + " (no service " + service + " yet)";
      return false;
    }
    if (!ros::service::call(service, t)) {
      missing = "the recorder " + recorder_ + " (" + service + " failed)";
      return false;
    }
    if (!t.response.success) missing = "the recorder " + recorder_ + " (" + t.response.message + ")";
    return t.response.success;
  }

  void onEstopTopic(const std_msgs::Bool& m) {
    if (m.data && coordinator_->state() != exec::RunState::EStopped)
      apply(coordinator_->emergencyStop(now(), "e-stop on /ddace/estop"));
  }

  bool srvStart(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    std::string missing;
    if (!ended_before_start_.empty()) {
      res.success = false;
      res.message = "not started: " + ended_before_start_;
      return true;
    }
    if (!connected(missing)) {
      res.success = false;
      res.message = "not started: waiting for " + missing;
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
    // stop_all: every wheel zeroed from here first, then the followers hear it.
    const bool answered = answer(coordinator_->emergencyStop(now(), "~estop service"), res, {exec::RunState::EStopped});
    std_msgs::Bool stop;
    stop.data = true;
    estop_pub_.publish(stop);  // the followers zero every wheel on receipt and refuse segments
    return answered;
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
    for (int e : coordinator_->lostEntities()) s.lost.push_back(spec_.entities[e].name);
    for (const auto& step : coordinator_->steps()) {
      for (const auto& t : step.tokens) {
        if (!t.token.isMotion() || t.started_s < 0 || t.state == exec::SegmentState::Done) continue;
        ddace::ActiveSegment a;
        a.entity = spec_.entities[t.token.entity].name;
        a.segment_id = t.segment_id;
        a.token = ros_exec::toMsg(t.token, spec_);
        a.status = static_cast<uint8_t>(t.state);
        a.progress = t.progress;
        a.distance_to_goal_m = t.distance_to_goal_m;
        a.elapsed_s = t.segment_id != 0 ? now() - t.segment_sent_s : 0.0;
        a.timeout_s = t.timeout_s;
        a.done_claimed = t.done_claimed;
        s.segments.push_back(a);
      }
    }
    for (const auto& step : coordinator_->steps()) s.completed_steps += step.complete ? 1 : 0;
    s.last_end_probability = -1;
    if (const auto& last = coordinator_->lastDecision()) {
      const auto& d = last->decision;
      const auto& p = last->probabilities;
      for (size_t i = 0; i < d.tokens.size(); ++i)
        s.last_decision.push_back(ros_exec::toMsg(d.tokens[i], spec_, i < p.tokens.size() ? p.tokens[i] : 1.0));
      s.last_decision_end = d.end;
      s.last_end_probability = p.end;
    }
    for (size_t k = 0; k < roles_.size(); ++k) s.roles.push_back(roles_.node(k));
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
    // Footprints (task.yaml's bodies): obstacles as grey discs, goals as flat green prints.
    for (size_t i = 0; i < obs.positions.size(); ++i) {
      const task::Footprint f = spec_.footprint(static_cast<int>(i));
      Marker body = base("footprints", Marker::CYLINDER);
      body.scale.x = body.scale.y = 2 * f.radius_m;
      body.scale.z = f.obstacle ? 0.03 : 0.001;
      body.pose.position = point(obs.positions[i], body.scale.z / 2);
      body.color.r = f.obstacle ? 0.6f : 0.2f;
      body.color.g = f.obstacle ? 0.6f : 0.8f;
      body.color.b = f.obstacle ? 0.6f : 0.3f;
      body.color.a = obs.tracked[i] ? 0.6f : 0.2f;
      arr.markers.push_back(body);
    }
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
        // ... its +-2 sigma band ...
        Marker band = base("band_2sigma", Marker::TRIANGLE_LIST);
        band.scale.x = band.scale.y = band.scale.z = 1.0;
        band.color = line.color;
        band.color.a = 0.25;
        for (const auto& p : exec::sigmaBandTriangles(tr.path, 2.0)) band.points.push_back(point(p, 0.001));
        if (!band.points.empty()) arr.markers.push_back(band);
        // ... and its end point.
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

  struct SentSegment {
    int entity;
    ddace::Segment msg;
  };
  std::unique_ptr<exec::Outbox> outbox_;
  std::map<uint32_t, ddace::DecisionRequest> sent_decisions_;
  std::map<uint32_t, ddace::PathRequest> sent_paths_;
  std::map<uint32_t, SentSegment> sent_segments_;

  struct Watched {
    size_t role;
    std::string topic, node;  ///< the node must be subscribed to this topic of ours
  };
  exec::RoleWatch roles_;
  std::vector<Watched> watched_;
  std::mutex links_mutex_;
  std::multiset<std::pair<std::string, std::string>> links_;  ///< (our topic, subscribed node)
  std::map<int, size_t> follower_role_;
  std::vector<std::pair<size_t, std::string>> heartbeat_roles_;  ///< (role, node) watched by ~heartbeat
  std::vector<ros::Subscriber> heartbeat_subs_;
  std::optional<size_t> pose_role_;
  std::string recorder_;  ///< node whose ~ready must succeed before a new run ("" = none)
  ros::WallTime next_autostart_try_;
  ros::WallTime autostart_deadline_;
  double start_timeout_s_ = 0;
  ros::WallTime next_ended_check_;
  std::string ended_before_start_;  ///< why the run cannot start: a role's node ended
  std::map<int, ros::Publisher> wheel_pubs_;
  std::vector<ros::Subscriber> wheel_subs_;

  ros::NodeHandle nh_;
  task::TaskSpec spec_;
  std::unique_ptr<exec::Coordinator> coordinator_;
  std::string frame_id_;
  double arrival_radius_m_ = task::kDefaultArrivalRadius;
  double stop_radius_m_ = task::kDefaultArrivalRadius;  ///< sent with every segment
  int path_points_ = 0;
  bool autostart_ = false;
  long entity_msgs_ = 0;
  std::map<int, ros::Publisher> segment_pubs_;
  std::vector<ros::Subscriber> status_subs_;
  ros::Publisher decision_pub_, path_pub_, estop_pub_, state_pub_, marker_pub_;
  ros::Subscriber entities_sub_, decision_sub_, path_sub_, estop_sub_;
  std::vector<ros::ServiceServer> services_;
  ros::Timer timer_, state_timer_, liveness_timer_;
};

CoordinatorNode::CoordinatorNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

CoordinatorNode::~CoordinatorNode() = default;

}  // namespace ddace::nodes
