// SimTableNode: see include/ddace/ros/sim_table.h.
#include "ddace/ros/sim_table.h"

#include <chrono>
#include <cmath>
#include <utility>
#include <map>
#include <memory>
#include <set>

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
  ros::SteadyTimer timer_, grace_timer_;
};

SimTableNode::SimTableNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

SimTableNode::~SimTableNode() = default;

}  // namespace ddace::nodes
