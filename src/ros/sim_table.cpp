// SimTableNode: see include/ddace/ros/sim_table.h.
#include "ddace/ros/sim_table.h"

#include <chrono>
#include <cmath>
#include <utility>
#include <map>
#include <memory>
#include <set>

#include <interactive_markers/interactive_marker_server.h>
#include <ros/ros.h>

#include <ddace/EntityArray.h>
#include <ddace/HamsterMockState.h>
#include <ddace/WheelCommand.h>

#include "command_sources.h"
#include "exec_conversions.h"
#include "params.h"
#include "ddace/common/error.h"
#include "ddace/exec/sim_table.h"
#include "ddace/vision/recorder.h"

namespace ddace::nodes {

namespace {

/// At most this many periods are stepped at once when the node fell behind (a loaded
/// machine): the table keeps pace with the wall clock, the robots' speeds stay true.
constexpr int kMaxCatchUpSteps = 5;
/// A goal has no body: its drag handle is a disc this large.
constexpr double kGoalHandleRadiusM = 0.02;
/// Drag handles float this high: above the tracker's markers and frames, so a click from
/// above picks the handle, not them.
constexpr double kHandleHeightM = 0.1;

}  // namespace

class SimTableNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const SimTableNode::Params defaults;
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    const task::TaskSpec spec = loadSpec(pnh, task_path);
    const auto [table_min, table_max] = tableExtent(pnh, defaults);
    const auto start =
        ros_exec::loadScene(pnh, spec, task_path, [&] { return exec::layoutScene(spec, table_min, table_max); });
    sim_ = std::make_unique<exec::SimTable>(spec, start, ros_exec::loadDiffDriveParams(ros::NodeHandle(pnh, "robot")));
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    const std::string wheels = rosparam::param(pnh, "wheels", defaults.wheels);
    const std::string state_topic = rosparam::param(pnh, "mock_state_topic", defaults.mock_state_topic);
    grace_s_ = rosparam::param(pnh, "wheels_grace_s", defaults.wheels_grace_s);
    if (wheels == "mock_hamster") {
      subs_.push_back(nh.subscribe(state_topic, 100, &Impl::onMockState, this));
      wheels_from_ = nh.resolveName(state_topic);
      grace_timer_ = nh.createSteadyTimer(ros::WallDuration(grace_s_), &Impl::reportSilentRobots, this, true);
    } else if (wheels == "commands") {
      for (const auto& e : spec.entities) {
        if (e.kind != task::EntityKind::Robot) continue;
        const std::string topic = "/robots/" + e.name + "/wheels";
        // As the robots' own drivers: commands count from the nodes the launch names only.
        auto& sources = sources_.emplace(e.name, ros_command::load(pnh, e.name)).first->second;
        subs_.push_back(nh.subscribe<ddace::WheelCommand>(
            topic, 10,
            boost::function<void(const ros::MessageEvent<const ddace::WheelCommand>&)>(
                [this, &sources, name = e.name, topic](const ros::MessageEvent<const ddace::WheelCommand>& ev) {
                  if (ros_command::accept(sources, ev, "sim_table", name))
                    drive(name, {ev.getMessage()->left_mps, ev.getMessage()->right_mps}, topic);
                })));
      }
      wheels_from_ = "/robots/<robot>/wheels";
    } else {
      throw Error("parameter '" + pnh.resolveName("wheels") + "' = '" + wheels +
                  "': expected mock_hamster (the mock Hamsters' wheels) or commands (/robots/<robot>/wheels)");
    }
    const std::string topic = rosparam::param(pnh, "entities_topic", defaults.entities_topic);
    pub_ = nh.advertise<ddace::EntityArray>(topic, 5);
    last_step_ = std::chrono::steady_clock::now();
    timer_ = nh.createSteadyTimer(ros::WallDuration(sim_->periodS()), &Impl::onTimer, this);
    if (rosparam::param(pnh, "drag", defaults.drag)) startDragging(pnh.resolveName("drag"));
    ROS_INFO("sim_table: task '%s', %zu entities with bodies at %.0f Hz; wheels from %s; true poses on %s",
             spec.name.c_str(), spec.entities.size(), 1.0 / sim_->periodS(), wheels_from_.c_str(),
             nh.resolveName(topic).c_str());
  }

 private:
  /// The task of ~task, or the one the recorder records (~recorder_file + ~markers_file).
  static task::TaskSpec loadSpec(ros::NodeHandle& pnh, const std::string& task_path) {
    const std::string recorder = rosparam::param<std::string>(pnh, "recorder_file", "");
    const std::string markers = rosparam::param<std::string>(pnh, "markers_file", "");
    if (task_path.empty() == recorder.empty() || (!recorder.empty() && markers.empty()))
      throw Error("give either '" + pnh.resolveName("task") + "' (a task directory) or '" +
                  pnh.resolveName("recorder_file") + "' and '" + pnh.resolveName("markers_file") +
                  "' (the task being recorded)");
    if (!task_path.empty()) return ros_exec::loadTaskSpec(task_path);
    return vision::loadRecorderConfig(recorder, vision::loadMarkerConfig(markers)).spec;
  }

  /// Where a scene is laid out: between the corner markers of ~markers_file, else on
  /// ~table_size from the origin (also when it is given).
  static std::pair<Eigen::Vector2d, Eigen::Vector2d> tableExtent(ros::NodeHandle& pnh,
                                                                 const SimTableNode::Params& defaults) {
    const std::string markers = rosparam::param<std::string>(pnh, "markers_file", "");
    const auto size = rosparam::optionalParam<std::vector<double>>(pnh, "table_size");
    if (size && size->size() != 2)
      throw Error("parameter '" + pnh.resolveName("table_size") + "' must be [width, depth] in metres");
    if (!size && !markers.empty()) {
      const vision::MarkerConfig config = vision::loadMarkerConfig(markers);
      if (!config.corners.empty()) {
        Eigen::Vector2d lo(INFINITY, INFINITY), hi(-INFINITY, -INFINITY);
        for (const auto& c : config.corners) {
          lo = lo.cwiseMin(Eigen::Vector2d(c.table_xy.x, c.table_xy.y));
          hi = hi.cwiseMax(Eigen::Vector2d(c.table_xy.x, c.table_xy.y));
        }
        return {lo, hi};
      }
    }
    const std::vector<double> wd = size.value_or(defaults.table_size);
    return {Eigen::Vector2d::Zero(), Eigen::Vector2d(wd[0], wd[1])};
  }

  void drive(const std::string& robot, const exec::WheelSpeeds& w, const std::string& source) {
    try {
      sim_->drive(robot, w, source);
      heard_.insert(robot);
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(1.0, "sim_table: %s", e.what());
    }
  }

  void onMockState(const ddace::HamsterMockState& m) {
    const int i = sim_->spec().entityIndex(m.robot);
    if (i < 0 || sim_->spec().entities[i].kind != task::EntityKind::Robot) {
      if (strangers_.insert(m.robot).second)
        ROS_WARN(
            "sim_table: mock Hamster %s is no robot of task '%s': its wheels move nothing on the simulated "
            "table (leave it out of the Hamster config to silence this)",
            m.robot.c_str(), sim_->spec().name.c_str());
      return;
    }
    drive(m.robot, {m.left_mps, m.right_mps}, wheels_from_);
  }

  void reportSilentRobots(const ros::SteadyTimerEvent&) {
    for (const auto& e : sim_->spec().entities)
      if (e.kind == task::EntityKind::Robot && !heard_.count(e.name))
        ROS_ERROR(
            "sim_table: no wheel speeds of robot %s on %s within %.1f s: it stands still (is it in the "
            "Hamster config, and the mock Hamsters running?)",
            e.name.c_str(), wheels_from_.c_str(), grace_s_);
  }

  /// One interactive marker per entity on `topic_ns` (rviz: Interact tool): a flat disc of
  /// its body, dropped where it should go.
  void startDragging(const std::string& topic_ns) {
    drag_server_ = std::make_unique<interactive_markers::InteractiveMarkerServer>(topic_ns);
    const task::TaskSpec& spec = sim_->spec();
    const auto entities = sim_->entities();
    for (size_t i = 0; i < spec.entities.size(); ++i) {
      visualization_msgs::InteractiveMarker m;
      m.header.frame_id = frame_id_;
      m.name = spec.entities[i].name;
      m.description = "drag " + m.name;
      m.pose.position.x = entities[i].pose.x;
      m.pose.position.y = entities[i].pose.y;
      m.pose.position.z = kHandleHeightM;
      m.pose.orientation.w = 1;
      const double radius_m = std::max(spec.footprint(static_cast<int>(i)).radius_m, kGoalHandleRadiusM);
      m.scale = static_cast<float>(3 * radius_m);
      visualization_msgs::InteractiveMarkerControl move;
      move.name = "move";
      move.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_PLANE;
      move.orientation.w = move.orientation.y = M_SQRT1_2;  // the plane's normal: the table's z
      move.always_visible = true;
      visualization_msgs::Marker disc;
      disc.type = visualization_msgs::Marker::CYLINDER;
      disc.scale.x = disc.scale.y = 2 * radius_m;
      disc.scale.z = 0.004;
      const bool robot = spec.entities[i].kind == task::EntityKind::Robot;
      disc.color.r = robot ? 0.2f : 0.9f, disc.color.g = 0.6f, disc.color.b = robot ? 1.0f : 0.2f;
      disc.color.a = 0.5f;
      move.markers.push_back(disc);
      m.controls.push_back(move);
      drag_server_->insert(m, [this](const auto& f) { onDrag(f); });
    }
    drag_server_->applyChanges();
    drag_timer_ = ros::NodeHandle().createSteadyTimer(ros::WallDuration(0.1), &Impl::showDrags, this);
    ROS_INFO(
        "sim_table: drag entities in rviz (Interact tool, %s): a robot drives to where it is dropped, a box or "
        "goal is carried there",
        topic_ns.c_str());
  }

  void onDrag(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& f) {
    using F = visualization_msgs::InteractiveMarkerFeedback;
    if (f->event_type == F::MOUSE_DOWN) held_.insert(f->marker_name);
    if (f->event_type == F::MOUSE_UP) held_.erase(f->marker_name);
    if (f->event_type != F::POSE_UPDATE && f->event_type != F::MOUSE_UP) return;
    if (!f->header.frame_id.empty() && f->header.frame_id != frame_id_) {
      ROS_WARN_THROTTLE(5.0,
                        "sim_table: a drag of %s in frame '%s' ignored: the markers are in '%s' (set rviz's "
                        "fixed frame to it)",
                        f->marker_name.c_str(), f->header.frame_id.c_str(), frame_id_.c_str());
      return;
    }
    try {
      sim_->drag(f->marker_name, {f->pose.position.x, f->pose.position.y}, "drag of " + f->client_id);
    } catch (const Error& e) {
      ROS_ERROR_THROTTLE(1.0, "sim_table: %s", e.what());
    }
  }

  /// Each marker not in a hand sits on its entity, or on where it was dropped while it goes there.
  void showDrags(const ros::SteadyTimerEvent&) {
    for (const std::string& note : sim_->takeDragNotes()) ROS_INFO("sim_table: %s", note.c_str());
    const auto entities = sim_->entities();
    const auto targets = sim_->dragTargets();
    for (size_t i = 0; i < entities.size(); ++i) {
      if (held_.count(entities[i].name)) continue;
      geometry_msgs::Pose p;
      p.position.x = targets[i] ? targets[i]->x() : entities[i].pose.x;
      p.position.y = targets[i] ? targets[i]->y() : entities[i].pose.y;
      p.position.z = kHandleHeightM;
      p.orientation.w = 1;
      drag_server_->setPose(entities[i].name, p);
    }
    drag_server_->applyChanges();
  }

  void onTimer(const ros::SteadyTimerEvent&) {
    const auto now = std::chrono::steady_clock::now();
    const auto period = std::chrono::duration<double>(sim_->periodS());
    int steps = 0;
    while (now - last_step_ >= period && steps < kMaxCatchUpSteps) {
      sim_->step();
      last_step_ += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
      ++steps;
    }
    if (steps == kMaxCatchUpSteps) last_step_ = now;  // far behind: the lost time is not replayed
    for (; contacts_seen_ < sim_->contacts().size(); ++contacts_seen_) {
      const auto& c = sim_->contacts()[contacts_seen_];
      ROS_INFO("sim_table: %s touched %s at t = %.2f s", sim_->spec().entities[c.a].name.c_str(),
               sim_->spec().entities[c.b].name.c_str(), c.time_s);
    }
    ddace::EntityArray msg;
    msg.header.stamp = ros::Time::now();
    msg.header.frame_id = frame_id_;
    for (const auto& e : sim_->entities()) {
      ddace::Entity out;
      out.name = e.name;
      out.kind = task::toString(e.kind);
      out.pose.x = e.pose.x;
      out.pose.y = e.pose.y;
      out.pose.theta = e.pose.yaw;
      out.visible = true;
      out.stale = false;
      out.last_seen = msg.header.stamp;
      msg.entities.push_back(out);
    }
    pub_.publish(msg);
  }

  std::unique_ptr<exec::SimTable> sim_;
  std::string frame_id_, wheels_from_;
  double grace_s_ = 0;
  std::set<std::string> heard_, strangers_;
  size_t contacts_seen_ = 0;
  std::chrono::steady_clock::time_point last_step_;
  std::map<std::string, CommandSources> sources_;  ///< wheels: commands; by robot (outlives subs_)
  std::vector<ros::Subscriber> subs_;
  ros::Publisher pub_;
  ros::SteadyTimer timer_, grace_timer_, drag_timer_;
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> drag_server_;
  std::set<std::string> held_;  ///< the markers a mouse holds now
};

SimTableNode::SimTableNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

SimTableNode::~SimTableNode() = default;

}  // namespace ddace::nodes
