// MockRobotNode: see include/ddace/ros/mock_robot.h.
#include "ddace/ros/mock_robot.h"

#include <map>
#include <memory>
#include <optional>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/String.h>
#include <tf2/LinearMath/Quaternion.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "command_sources.h"
#include "exec_conversions.h"
#include "params.h"
#include "ddace/exec/scene.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/task/task_dir.h"

namespace ddace::nodes {

class MockRobotNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) : updater_(nh, pnh) {
    rosparam::alsoReads(pnh, {"diagnostic_period"});  // diagnostic_updater's
    updater_.setHardwareID("mock_robots");
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = ros_exec::loadTaskSpec(task_path);
    const MockRobotNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    publish_tf_ = rosparam::param(pnh, "publish_tf", defaults.publish_tf);
    const exec::TableSimulatorParams sp = ros_exec::loadTableParams(pnh, defaults);
    const exec::DiffDriveParams dp = ros_exec::loadDiffDriveParams(ros::NodeHandle(pnh, "robot"));
    const auto stalled = rosparam::param(pnh, "stalled", std::vector<std::string>{});
    for (const auto& s : stalled) {
      const int i = spec_.entityIndex(s);
      if (i < 0 || spec_.entities[i].kind != task::EntityKind::Robot)
        throw Error("parameter '" + pnh.resolveName("stalled") + "' names '" + s + "', not a robot of the task");
    }
    sim_ = std::make_unique<exec::TableSimulator>(spec_, ros_exec::loadScene(pnh, spec_, task_path), dp, sp, stalled);
    for (const auto& s : stalled) ROS_WARN("mock_robots: %s is stalled (its wheels do not turn)", s.c_str());

    const size_t n = spec_.entities.size();
    for (size_t i = 0; i < n; ++i) {
      const auto& te = spec_.entities[i];
      const int k = static_cast<int>(i);
      if (te.kind == task::EntityKind::Robot) {
        // Wheel commands count from the nodes the launch names only, as on the real bridge.
        auto& sources = sources_.emplace(k, ros_command::load(pnh, te.name)).first->second;
        subs_.push_back(nh.subscribe<ddace::WheelCommand>(
            "/robots/" + te.name + "/wheels", 10,
            boost::function<void(const ros::MessageEvent<const ddace::WheelCommand>&)>(
                [this, k, &sources, name = te.name](const ros::MessageEvent<const ddace::WheelCommand>& ev) {
                  if (ros_command::accept(sources, ev, "mock_robots", name))
                    sim_->commandWheels(k, {ev.getMessage()->left_mps, ev.getMessage()->right_mps});
                })));
        // What the interlock refused, in the diagnostics as the bridge's.
        updater_.add("mock robot " + te.name, [this, k](diagnostic_updater::DiagnosticStatusWrapper& s) {
          s.summary(diagnostic_msgs::DiagnosticStatus::OK, "simulated");
          ros_command::diagnose(sources_.at(k), reported_foreign_[k], s);
        });
        // A carrier's segments and their ends: its load rides with it, or is pushed by it
        // (loads_ride, exec::TableSimulator::carry).
        subs_.push_back(
            nh.subscribe<ddace::Segment>("/robots/" + te.name + "/segment", 10,
                                         [this, k](const ddace::Segment::ConstPtr& m) { onRobotSegment(k, *m); }));
        subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
            "/robots/" + te.name + "/segment_status", 20,
            [this, k](const ddace::SegmentStatus::ConstPtr& m) { onRobotStatus(k, *m); }));
      } else if (te.kind == task::EntityKind::Object) {
        status_pubs_[k] = nh.advertise<ddace::SegmentStatus>("/robots/" + te.name + "/segment_status", 10);
        subs_.push_back(
            nh.subscribe<ddace::Segment>("/robots/" + te.name + "/segment", 10,
                                         [this, k](const ddace::Segment::ConstPtr& m) { onObjectSegment(k, *m); }));
      }
    }
    const std::string topic = rosparam::param(pnh, "entities_topic", defaults.entities_topic);
    entities_pub_ = nh.advertise<ddace::EntityArray>(topic, 5);
    estop_sub_ = nh.subscribe("/ddace/estop", 5, &Impl::onEstop, this);
    // A hand on the table (perturbation tests): puts a body down elsewhere, holds a robot.
    subs_.push_back(pnh.subscribe<ddace::Entity>(
        "place", 5,
        [this, topic = pnh.resolveName("place")](const ddace::Entity::ConstPtr& m) { onPlace(topic, *m); }));
    for (const bool hold : {true, false}) {
      const std::string t = pnh.resolveName(hold ? "hold" : "release");
      subs_.push_back(pnh.subscribe<std_msgs::String>(
          hold ? "hold" : "release", 5,
          [this, hold, t](const std_msgs::String::ConstPtr& m) { onHold(t, m->data, hold); }));
    }
    subs_.push_back(pnh.subscribe<std_msgs::String>(
        "lose", 5, [this, t = pnh.resolveName("lose")](const std_msgs::String::ConstPtr& m) { onLose(t, m->data); }));
    timer_ = nh.createTimer(ros::Duration(sim_->periodS()), &Impl::onTimer, this);
    if (publish_tf_) publishStaticFrames();
    diag_timer_ =
        nh.createSteadyTimer(ros::WallDuration(0.1), [this](const ros::SteadyTimerEvent&) { updater_.update(); });
    ROS_INFO("mock_robots: task '%s', %zu entities at %.0f Hz on %s, %s, loads %s", spec_.name.c_str(), n, dp.rate_hz,
             topic.c_str(), sp.bodies ? "with bodies (Box2D)" : "points without bodies",
             sp.loads_ride ? "riding in front of their carriers" : "pushed by their carriers");
  }

 private:
  void publish(const exec::ObjectStatus& s) {
    status_pubs_.at(s.entity).publish(ros_exec::statusMsg(s, spec_));
    // Ended: the object's segment is forgotten (a later robot segment must not pair with it).
    const auto it = running_.find(s.entity);
    if (it != running_.end() && it->second.segment_id == s.segment_id &&
        (s.state == exec::SegmentState::Done || s.state == exec::SegmentState::Failed ||
         s.state == exec::SegmentState::Aborted))
      running_.erase(it);
  }
  void publish(const std::optional<exec::ObjectStatus>& s) {
    if (s) publish(*s);
  }

  void onObjectSegment(int i, const ddace::Segment& m) {
    running_.erase(i);
    if (m.mode == ddace::Segment::MODE_STOP) return publish(sim_->stopSegment(i));
    const std::string topic = "/robots/" + spec_.entities[i].name + "/segment";
    exec::PlannedPath p;
    try {
      p = ros_exec::fromMsg(m.path, m.stddev_m, topic);
    } catch (const std::exception& ex) {
      return publish(sim_->refuseSegment(i, m.segment_id, ex.what()));
    }
    const auto status = sim_->startSegment(i, m.segment_id, p.points);
    publish(status);
    if (status && status->state != exec::SegmentState::Accepted) return;
    if (auto t = token(m)) {
      running_[i] = {m.step, m.segment_id, *t};
      for (const auto& [r, seg] : running_)
        if (spec_.entities[r].kind == task::EntityKind::Robot) pair(r, i);
    }
  }

  /// The segment's token, or nothing (a malformed token: the follower refuses the segment).
  std::optional<task::Token> token(const ddace::Segment& m) const { return ros_exec::tokenOrNothing(m.token, spec_); }

  void onRobotSegment(int r, const ddace::Segment& m) {
    const auto was = running_.find(r);
    if (was != running_.end()) {
      if (m.mode != ddace::Segment::MODE_STOP && m.segment_id == was->second.segment_id) return;  // a re-sent copy
      running_.erase(was);
      dropLoad(r);  // replaced before it ended: its load no longer rides (the follower drops it too)
    }
    if (m.mode == ddace::Segment::MODE_STOP) return dropLoad(r);
    if (auto t = token(m)) {
      running_[r] = {m.step, m.segment_id, *t};
      for (const auto& [o, seg] : running_)
        if (spec_.entities[o].kind == task::EntityKind::Object) pair(r, o);
    }
  }

  /// Robot r's running segment and object o's are a carry: the load goes with it, riding or
  /// pushed (when it is at the carrier; else it moves along its own path).
  void pair(int r, int o) {
    const Running& a = running_.at(r);
    const Running& b = running_.at(o);
    if (sim_->carrierOf(o) >= 0 || !exec::carries(spec_, a.step, a.token, b.step, b.token)) return;
    if (sim_->carry(r, o))
      ROS_INFO("mock_robots: %s goes with %s (step %d)", spec_.entities[o].name.c_str(), spec_.entities[r].name.c_str(),
               a.step + 1);
  }

  /// The carrier's segment ended: DONE -- a riding load goes on to its end (on the target),
  /// a pushed one is judged where it lies, and reports DONE or FAILED; FAILED or ABORTED --
  /// the load stops where it is (ABORTED).
  void onRobotStatus(int r, const ddace::SegmentStatus& m) {
    const auto it = running_.find(r);
    if (it == running_.end() || m.segment_id != it->second.segment_id) return;
    if (m.status == ddace::SegmentStatus::DONE) {
      for (size_t o = 0; o < spec_.entities.size(); ++o)
        if (sim_->carrierOf(static_cast<int>(o)) == r) sim_->endCarry(static_cast<int>(o));
      running_.erase(it);
    } else if (m.status == ddace::SegmentStatus::FAILED || m.status == ddace::SegmentStatus::ABORTED) {
      running_.erase(it);
      dropLoad(r);
    }
  }
  void dropLoad(int r) {
    for (size_t o = 0; o < spec_.entities.size(); ++o)
      if (sim_->carrierOf(static_cast<int>(o)) == r) publish(sim_->stopSegment(static_cast<int>(o)));
  }

  /// Goals never move: their frames go on /tf_static once (latched), not at 50 Hz on /tf.
  void publishStaticFrames() {
    std::vector<geometry_msgs::TransformStamped> frames;
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      if (spec_.entities[i].kind != task::EntityKind::Goal) continue;
      frames.push_back(transform(spec_.entities[i].name, sim_->truePose(static_cast<int>(i)), ros::Time::now()));
    }
    if (!frames.empty()) static_tf_.sendTransform(frames);
  }

  geometry_msgs::TransformStamped transform(const std::string& child, const exec::Pose2D& pose,
                                            const ros::Time& stamp) const {
    geometry_msgs::TransformStamped t;
    t.header.stamp = stamp;
    t.header.frame_id = frame_id_;
    t.child_frame_id = child;
    t.transform.translation.x = pose.x;
    t.transform.translation.y = pose.y;
    tf2::Quaternion q;
    q.setRPY(0, 0, pose.yaw);
    t.transform.rotation.x = q.x();
    t.transform.rotation.y = q.y();
    t.transform.rotation.z = q.z();
    t.transform.rotation.w = q.w();
    return t;
  }

  /// Index of entity `name` of `kind`, or -1 after logging why `topic` refused it.
  int entityNamed(const std::string& topic, const std::string& name, bool robot_only) const {
    const int i = spec_.entityIndex(name);
    const bool body = i >= 0 && spec_.entities[i].kind != task::EntityKind::Goal;
    if (body && (!robot_only || spec_.entities[i].kind == task::EntityKind::Robot)) return i;
    ROS_ERROR("mock_robots: %s names '%s', not a %s of the task: ignored", topic.c_str(), name.c_str(),
              robot_only ? "robot" : "robot or object");
    return -1;
  }
  void onPlace(const std::string& topic, const ddace::Entity& m) {
    const int i = entityNamed(topic, m.name, false);
    if (i < 0) return;
    try {
      sim_->place(i, {m.pose.x, m.pose.y});
    } catch (const std::exception& ex) {
      ROS_ERROR("mock_robots: %s: %s", topic.c_str(), ex.what());
      return;
    }
    ROS_WARN("mock_robots: a hand put %s down at (%.3f, %.3f)", m.name.c_str(), m.pose.x, m.pose.y);
  }
  void onHold(const std::string& topic, const std::string& name, bool hold) {
    const int i = entityNamed(topic, name, true);
    if (i < 0) return;
    sim_->setStalled(i, hold);
    ROS_WARN("mock_robots: %s %s", name.c_str(), hold ? "held (its wheels do not turn)" : "released");
  }

  /// The robot's battery dies: its wheels stop for good and the tracker holds its last pose,
  /// stale, from now on.
  void onLose(const std::string& topic, const std::string& name) {
    const int i = entityNamed(topic, name, true);
    if (i < 0 || lost_.count(i)) return;
    sim_->setStalled(i, true);
    lost_[i] = {sim_->measuredPose(i), ros::Time::now()};
    ROS_WARN("mock_robots: %s lost (its wheels stop, the tracker holds its last pose, stale)", name.c_str());
  }

  void onEstop(const std_msgs::Bool& m) {
    for (const auto& s : sim_->setEstop(m.data)) publish(s);
  }

  void onTimer(const ros::TimerEvent&) {
    for (const auto& s : sim_->step()) publish(s);
    for (; contacts_seen_ < sim_->contacts().size(); ++contacts_seen_) {
      const auto& c = sim_->contacts()[contacts_seen_];
      ROS_WARN("mock_robots: contact %zu: %s touched %s at t = %.2f s", contacts_seen_ + 1,
               spec_.entities[c.a].name.c_str(), spec_.entities[c.b].name.c_str(), c.time_s);
    }
    ddace::EntityArray msg;
    msg.header.stamp = ros::Time::now();
    msg.header.frame_id = frame_id_;
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto lost = lost_.find(static_cast<int>(i));
      const exec::Pose2D measured = lost != lost_.end() ? lost->second.first : sim_->measuredPose(static_cast<int>(i));
      ddace::Entity out;
      out.name = spec_.entities[i].name;
      out.kind = task::toString(spec_.entities[i].kind);
      out.pose.x = measured.x;
      out.pose.y = measured.y;
      out.pose.theta = measured.yaw;
      out.visible = lost == lost_.end();
      out.stale = !out.visible;
      out.last_seen = out.visible ? msg.header.stamp : lost->second.second;
      msg.entities.push_back(out);
      if (publish_tf_ && spec_.entities[i].kind != task::EntityKind::Goal)
        tf_.sendTransform(transform(out.name, measured, msg.header.stamp));
    }
    entities_pub_.publish(msg);
  }

  task::TaskSpec spec_;
  std::unique_ptr<exec::TableSimulator> sim_;
  struct Running {
    int step = -1;
    uint32_t segment_id = 0;
    task::Token token;
  };
  std::map<int, Running> running_;  ///< each entity's running segment (robots: as sent to their follower)
  size_t contacts_seen_ = 0;        ///< contacts already logged
  std::map<int, std::pair<exec::Pose2D, ros::Time>> lost_;  ///< robots lost (~lose): last pose and when seen
  std::string frame_id_;
  bool publish_tf_ = true;                    // set from the parameters
  std::map<int, CommandSources> sources_;     ///< by robot index: whose wheel commands count
  std::map<int, uint64_t> reported_foreign_;  ///< by robot index: foreign commands at the last diagnostics
  diagnostic_updater::Updater updater_;
  ros::SteadyTimer diag_timer_;
  std::vector<ros::Subscriber> subs_;
  std::map<int, ros::Publisher> status_pubs_;  ///< by object index
  ros::Publisher entities_pub_;
  ros::Subscriber estop_sub_;
  ros::Timer timer_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
};

MockRobotNode::MockRobotNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

MockRobotNode::~MockRobotNode() = default;

}  // namespace ddace::nodes
