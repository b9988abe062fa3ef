// HamsterBridgeNode: see include/ddace/ros/hamster_bridge.h.
#include "ddace/ros/hamster_bridge.h"

#include <poll.h>
#include <ros/ros.h>
#include <diagnostic_updater/diagnostic_updater.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>

#include <ddace/HamsterEffects.h>
#include <ddace/HamsterSensors.h>
#include <ddace/WheelCommand.h>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/task/task_spec.h"
#include "ddace/hamster/config.h"
#include "ddace/hamster/link.h"
#include "ddace/hamster/link_dir.h"
#include "ddace/ros/hamster_conversions.h"

#include "command_sources.h"
#include "params.h"

namespace ddace::nodes {

using namespace hamster;

namespace {

/// The robots of the task in `task_dir` (~task, as the launch files pass it): only they are
/// connected. The configured robots the task does not have are named, so that a config
/// of another task never goes unnoticed.
std::vector<std::string> taskRobots(const std::string& task_dir, const BridgeConfig& config,
                                    const std::string& config_path) {
  const task::TaskSpec spec = task::readTaskYaml(task_dir + "/task.yaml");
  std::vector<std::string> robots;
  for (const auto& e : spec.entities)
    if (e.kind == task::EntityKind::Robot) robots.push_back(e.name);
  const std::string warning = unusedRobotsWarning(config, robots, spec.name, config_path);
  if (!warning.empty()) ROS_WARN("hamster_bridge: %s", warning.c_str());
  return robots;
}

/// `name` in this node's namespace, e.g. /mock_hamster beside /hamster_bridge.
std::string siblingName(const std::string& name) {
  return ros::names::append(ros::names::parentNamespace(ros::this_node::getName()), name);
}

/// The pid parameter `param` states (cached: the master tells of changes), if set.
std::optional<long> statedPid(const std::string& param) {
  int pid = 0;
  if (!ros::param::getCached(param, pid) || pid <= 0) return std::nullopt;
  return pid;
}

}  // namespace

class HamsterBridgeNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) : updater_(nh, pnh) {
    ddace::rosparam::alsoReads(pnh, {"diagnostic_period"});  // diagnostic_updater's
    const std::string config_path =
        ddace::rosparam::requireString(pnh, "config", "path of the Hamster config YAML, e.g. config/hamsters.yaml");
    config_ = loadBridgeConfig(config_path);
    config_.port_dir = ddace::rosparam::param(pnh, "port_dir", config_.port_dir);
    config_.scan = ddace::rosparam::param(pnh, "scan", config_.scan);
    const std::string mock_link_dir = ddace::rosparam::param<std::string>(pnh, "mock_link_dir", "");
    if (!mock_link_dir.empty()) useMockLinks(config_, mock_link_dir);
    // The pid the run's mock node states once it holds the link directory's claim.
    const std::string mock_pid_param =
        ros::names::append(ddace::rosparam::param<std::string>(pnh, "mock_node", siblingName("mock_hamster")), "pid");
    auto only = ddace::rosparam::param(pnh, "robots", std::vector<std::string>{});
    const std::string task = ddace::rosparam::param<std::string>(pnh, "task", "");
    std::string what = "parameter ~robots";
    if (!task.empty() && only.empty()) {
      only = taskRobots(task, config_, config_path);
      what = "task " + task + " (parameter ~task)";  // a robot of the task the config lacks
    }
    updater_.setHardwareID("hamster_bridge");
    auto ports = std::make_shared<PortDirectory>();
    for (const auto& r : selectRobots(config_, only, what, config_path)) {
      auto robot = std::make_unique<Robot>(ddace::ros_command::load(pnh, r.name));
      const TransportFactory factory =
          mock_link_dir.empty()
              ? transportFactoryFor(r, config_)
              : mockLinkTransportFactory(
                    mock_link_dir, [mock_pid_param] { return statedPid(mock_pid_param); }, config_.rtscts);
      robot->link = std::make_unique<RobotLink>(r, config_, ports, factory);
      const std::string base = "/robots/" + r.name;
      Robot* raw = robot.get();
      robot->sensors = nh.advertise<ddace::HamsterSensors>(base + "/sensors", 10);
      robot->wheels = nh.subscribe<ddace::WheelCommand>(
          base + "/wheels", 1,
          boost::function<void(const ros::MessageEvent<const ddace::WheelCommand>&)>(
              [this, raw](const ros::MessageEvent<const ddace::WheelCommand>& ev) { onWheels(*raw, ev); }),
          ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
      robot->effects = nh.subscribe<ddace::HamsterEffects>(
          base + "/effects", 1, [this, raw](const ddace::HamsterEffects::ConstPtr& m) { onEffects(*raw, *m); });
      updater_.add("hamster " + r.name,
                   [this, raw](diagnostic_updater::DiagnosticStatusWrapper& s) { diagnose(*raw, s); });
      const std::string reach = r.transport == TransportKind::Ble ? "direct BLE via " + r.ble_adapter
                                                                  : "port hints [" + join(r.port_hints) + "]";
      ROS_INFO("hamster_bridge: %s = %s (%s), %s; wheel commands from [%s] only", r.name.c_str(),
               r.address.display().c_str(), r.model == Model::Unknown ? "model auto" : modelName(r.model).c_str(),
               reach.c_str(), raw->sources.allowedList().c_str());
      robots_.push_back(std::move(robot));
    }
    ROS_INFO("hamster_bridge: %zu robots; ports under %s, scanning [%s]%s", robots_.size(), config_.port_dir.c_str(),
             join(config_.scan).c_str(),
             mock_link_dir.empty() ? ""
                                   : ("; mock Hamsters only: links to pseudo-terminals of the mock whose pid " +
                                      mock_pid_param + " states, holding the directory's claim")
                                         .c_str());
    diag_timer_ =
        nh.createSteadyTimer(ros::WallDuration(0.1), [this](const ros::SteadyTimerEvent&) { updater_.update(); });
  }

  /// The I/O loop: wait for bytes on any port (at most 2 ms, so identification and
  /// link timers run), let every link do its work, publish the sensor lines.
  void run() {
    std::vector<pollfd> fds;
    std::vector<ddace::hamster::CycleReport> reports;
    while (ros::ok()) {
      fds.clear();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        for (const auto& r : robots_) {
          if (r->link->fd() >= 0) fds.push_back({r->link->fd(), POLLIN, 0});
        }
      }
      if (fds.empty()) {
        ros::WallDuration(0.002).sleep();
      } else {
        ::poll(fds.data(), fds.size(), 2);
      }
      for (auto& r : robots_) {
        reports.clear();
        LinkState before, after;
        std::string error;
        std::vector<std::string> warnings;
        {
          std::lock_guard<std::mutex> lock(mutex_);
          before = r->link->state();
          r->link->poll(monotonicS(), reports);
          after = r->link->state();
          error = r->link->stats().last_error;
          warnings = r->link->takeWarnings();
        }
        for (const auto& w : warnings) ROS_WARN("hamster_bridge: %s: %s", r->link->robot().name.c_str(), w.c_str());
        if (before != after) logTransition(*r, before, after, error);
        for (const auto& report : reports) {
          ddace::HamsterSensors msg =
              ddace::ros_hamster::toSensorsMsg(r->link->robot(), r->link->model(), report, r->memory);
          msg.header.stamp = ros::Time::now();
          r->last_rssi_dbm = msg.rssi_dbm;
          r->sensors.publish(msg);
        }
      }
    }
  }

 private:
  struct Robot {
    explicit Robot(CommandSources s) : sources(std::move(s)) {}
    CommandSources sources;  // guarded by mutex_, as the link
    uint64_t diag_foreign = 0;
    std::unique_ptr<RobotLink> link;
    ros::Publisher sensors;
    ros::Subscriber wheels, effects;
    ddace::ros_hamster::SensorMemory memory;
    std::atomic<int> last_rssi_dbm{0};  // written by the I/O loop, read by diagnostics
    uint64_t diag_lines = 0;
    uint64_t diag_losses = 0;
    double diag_time_s = -1.0;
  };

  static std::string join(const std::vector<std::string>& items) {
    std::string out;
    for (const auto& i : items) out += (out.empty() ? "" : ", ") + i;
    return out;
  }

  void logTransition(const Robot& r, LinkState before, LinkState after, const std::string& error) {
    const std::string& name = r.link->robot().name;
    if (after == LinkState::Streaming) {
      ROS_INFO("hamster_bridge: %s streaming on %s (%s %s)", name.c_str(), r.link->port().c_str(),
               modelName(r.link->model()).c_str(), r.link->robot().address.display().c_str());
    } else if (after == LinkState::Identified) {
      ROS_INFO("hamster_bridge: %s: the dongle on %s answers for %s; waiting for the robot's first sensor line",
               name.c_str(), r.link->port().c_str(), r.link->robot().address.display().c_str());
    } else if (after == LinkState::Lost) {
      ROS_WARN("hamster_bridge: %s link lost (%s); wheels zeroed, waiting on %s", name.c_str(), error.c_str(),
               r.link->port().c_str());
    } else if (before == LinkState::Streaming || before == LinkState::Lost || before == LinkState::Identified) {
      ROS_WARN("hamster_bridge: %s: port closed (%s); wheels zeroed, searching", name.c_str(), error.c_str());
    } else if (after == LinkState::Searching && !error.empty()) {
      ROS_DEBUG("hamster_bridge: %s: %s", name.c_str(), error.c_str());
    }
  }

  void onWheels(Robot& r, const ros::MessageEvent<const ddace::WheelCommand>& ev) {
    const ddace::WheelCommand& m = *ev.getMessage();
    // The stale-stamp rule is RobotLink's (command_max_age_s); the age is on ROS time.
    // Unstamped commands never get here (the interlock refuses them).
    const double age = (ros::Time::now() - m.header.stamp).toSec();
    std::lock_guard<std::mutex> lock(mutex_);
    if (!ddace::ros_command::accept(r.sources, ev, "hamster_bridge", r.link->robot().name)) return;
    try {
      r.link->setWheelCommand(m.left_mps, m.right_mps, monotonicS(), age);
    } catch (const ddace::Error& e) {
      ROS_WARN_THROTTLE(1.0, "hamster_bridge: /robots/%s/wheels: command refused: %s", r.link->robot().name.c_str(),
                        e.what());
    }
  }

  void onEffects(Robot& r, const ddace::HamsterEffects& m) {
    try {
      const auto e = ddace::ros_hamster::fromEffectsMsg(m);
      std::lock_guard<std::mutex> lock(mutex_);
      r.link->setEffects(e.left_rgb, e.right_rgb, e.buzzer_hz, e.note);
    } catch (const ddace::Error& e) {
      ROS_WARN_THROTTLE(1.0, "hamster_bridge: /robots/%s/effects refused: %s", r.link->robot().name.c_str(), e.what());
    }
  }

  void diagnose(Robot& r, diagnostic_updater::DiagnosticStatusWrapper& s) {
    LinkStats st;
    LinkState state;
    std::string port;
    Model model;
    double last_line, battery_v;
    LinkHealth health;
    std::optional<CommandSources> sources;
    const double now = monotonicS();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      st = r.link->stats();
      state = r.link->state();
      port = r.link->port();
      model = r.link->model();
      last_line = r.link->lastLineTime();
      battery_v = r.link->batteryV();
      // A flapping link must show even if it happens to be up at the moment of the report.
      health = r.link->health(now, st.link_losses - r.diag_losses);
      sources = r.sources;
    }
    double rate = 0.0;
    if (r.diag_time_s > 0 && now > r.diag_time_s) rate = (st.lines_ok - r.diag_lines) / (now - r.diag_time_s);
    r.diag_lines = st.lines_ok;
    r.diag_losses = st.link_losses;
    r.diag_time_s = now;
    using Level = LinkHealth::Level;
    s.summary(health.level == Level::Ok     ? diagnostic_msgs::DiagnosticStatus::OK
              : health.level == Level::Warn ? diagnostic_msgs::DiagnosticStatus::WARN
                                            : diagnostic_msgs::DiagnosticStatus::ERROR,
              health.summary);
    const RobotConfig& cfg = r.link->robot();
    s.add("link state", linkStateName(state));
    s.add("address", cfg.address.display());
    s.add("model", modelName(model));
    s.add("port", port);
    s.add("line rate (Hz)", rate);
    s.add("last valid line age (s)", last_line < 0 ? -1.0 : now - last_line);
    s.add("valid lines", st.lines_ok);
    s.add("dropped lines", st.lines_dropped);
    s.add("last drop reason", st.last_drop_reason);
    s.add("motoring lines sent", st.lines_sent);
    s.add("write failures", st.write_failures);
    s.add("zero-wheel cycles (no fresh command)", st.stale_command_cycles);
    s.add("saturated cycles", st.saturated_cycles);
    s.add("refused commands", st.refused_commands);
    s.add("connects", st.connects);
    s.add("link losses", st.link_losses);
    s.add("no-robot lines", st.no_robot_lines);
    s.add("battery (V)", battery_v);
    s.add("signal (dBm)", r.last_rssi_dbm.load());
    s.add("last error", st.last_error);
    ddace::ros_command::diagnose(*sources, r.diag_foreign, s);
  }

  BridgeConfig config_;
  diagnostic_updater::Updater updater_;
  ros::SteadyTimer diag_timer_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<Robot>> robots_;
};

HamsterBridgeNode::HamsterBridgeNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : impl_(std::make_unique<Impl>(nh, pnh)) {}

HamsterBridgeNode::~HamsterBridgeNode() = default;

void HamsterBridgeNode::run() {
  impl_->run();
}

}  // namespace ddace::nodes
