// MockHamsterNode: see include/ddace/ros/mock_hamster.h.
#include "ddace/ros/mock_hamster.h"

#include <ros/ros.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <tuple>

#include <ddace/EntityArray.h>
#include <ddace/HamsterMockFault.h>
#include <ddace/HamsterMockState.h>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/hamster/config.h"
#include "ddace/hamster/link_dir.h"
#include "ddace/hamster/mock_robot.h"

#include "ddace/ros/frames.h"
#include "params.h"

namespace ddace::nodes {

using namespace hamster;

class MockHamsterNode::Impl {
 public:
  Impl(ros::NodeHandle& /*nh*/, ros::NodeHandle& pnh) {
    const std::string config_path = ddace::rosparam::requireString(pnh, "config", "Hamster config YAML");
    const std::string link_dir = ddace::rosparam::requireString(pnh, "link_dir", "directory for the pty symlinks");
    const BridgeConfig config = loadBridgeConfig(config_path);
    const auto only = ddace::rosparam::param(pnh, "robots", std::vector<std::string>{});
    const std::optional<double> true_mps = ddace::rosparam::optionalParam<double>(pnh, "true_mps_per_unit");
    if (true_mps && !(*true_mps > 0.0)) throw ddace::Error("parameter ~true_mps_per_unit must be > 0");
    const double robot_timeout_s = ddace::rosparam::param(pnh, "robot_timeout_s", MockRobotSettings{}.robot_timeout_s);
    frame_id_ = ddace::rosparam::param<std::string>(pnh, "frame_id", kTableFrame);
    const std::vector<RobotConfig> chosen = selectRobots(config, only, "parameter ~robots", config_path);
    std::vector<MockRobotSettings> settings;
    std::vector<std::string> link_names;
    for (size_t index = 0; index < chosen.size(); ++index) {
      settings.push_back(mockSettingsFor(chosen[index], index, link_dir, true_mps, robot_timeout_s));
      link_names.push_back(settings.back().link_path.substr(link_dir.size() + 1));
    }
    // This run's own links only: another live run's directory is refused, not shared.
    claim_ = std::make_unique<LinkDirClaim>(
        link_dir, link_names, "parameter " + pnh.resolveName("link_dir") + " (launch argument mock_link_dir)");
    // Whose claim it is, for the bridge of this graph (its ~mock_link_dir): it opens no link
    // of a directory another process holds.
    pnh.setParam("pid", static_cast<int>(::getpid()));
    for (const MockRobotSettings& s : settings) {
      robots_.push_back(std::make_unique<MockRobot>(s));
      ROS_INFO("mock_hamster: %s (%s, %s) on %s -> %s", s.name.c_str(), modelName(s.model).c_str(),
               s.address.display().c_str(), s.link_path.c_str(), robots_.back()->slavePath().c_str());
    }
    if (robots_.empty()) throw ddace::Error("no robots to simulate (check ~config and ~robots)");
    state_pub_ = pnh.advertise<ddace::HamsterMockState>("state", 50);
    entities_pub_ = pnh.advertise<ddace::EntityArray>("entities", 5);
    fault_sub_ = pnh.subscribe<ddace::HamsterMockFault>(
        "fault", 10, [this](const ddace::HamsterMockFault::ConstPtr& m) { onFault(*m); });
    state_timer_ =
        pnh.createSteadyTimer(ros::WallDuration(0.02), [this](const ros::SteadyTimerEvent&) { publishStates(); });
    entity_timer_ = pnh.createSteadyTimer(ros::WallDuration(1.0 / 30.0),
                                          [this](const ros::SteadyTimerEvent&) { publishEntities(); });
  }

  ~Impl() {
    robots_.clear();  // removes the symlinks, then the claim what it created
  }

  /// Steps every simulated robot each millisecond.
  void run() {
    while (ros::ok()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        const double now = monotonicS();
        for (auto& r : robots_) r->step(now);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

 private:
  void onFault(const ddace::HamsterMockFault& m) {
    MockFault fault;
    try {
      fault = parseMockFault(m.fault);
    } catch (const ddace::Error& e) {
      ROS_ERROR("mock_hamster: ~fault: %s", e.what());
      return;
    }
    std::lock_guard<std::mutex> lock(mutex_);
    bool found = false;
    for (auto& r : robots_) {
      if (m.robot == "*" || m.robot == r->settings().name) {
        r->setFault(fault, m.duration_s, monotonicS());
        ROS_INFO("mock_hamster: %s: fault %s for %.2f s", r->settings().name.c_str(), m.fault.c_str(), m.duration_s);
        found = true;
      }
    }
    if (!found) ROS_ERROR("mock_hamster: ~fault: no robot named '%s'", m.robot.c_str());
  }

  void publishStates() {
    std::lock_guard<std::mutex> lock(mutex_);
    const double now = monotonicS();
    for (const auto& r : robots_) {
      ddace::HamsterMockState s;
      s.header.stamp = ros::Time::now();
      s.header.frame_id = frame_id_;
      s.robot = r->settings().name;
      s.address = r->settings().address.display();
      s.port = r->slavePath();
      s.fault = mockFaultName(r->fault());
      s.driven = r->driven(now);
      s.left_units = r->leftUnits();
      s.right_units = r->rightUnits();
      std::tie(s.left_mps, s.right_mps) = r->wheelMps(now);
      const Effector& e = r->effector();
      auto colour = [](const std::array<uint8_t, 3>& rgb) {
        std_msgs::ColorRGBA c;
        c.r = rgb[0] / 255.0f;
        c.g = rgb[1] / 255.0f;
        c.b = rgb[2] / 255.0f;
        c.a = 1.0f;
        return c;
      };
      s.left_led = colour(e.left_led_rgb);
      s.right_led = colour(e.right_led_rgb);
      s.buzzer_hz = e.buzzer_hz;
      s.note = e.note;
      s.motoring_lines = r->motoringLines();
      s.bad_lines = r->badLines();
      s.identify_requests = r->identifyRequests();
      s.pose.x = r->x();
      s.pose.y = r->y();
      s.pose.theta = r->theta();
      state_pub_.publish(s);
    }
  }

  void publishEntities() {
    std::lock_guard<std::mutex> lock(mutex_);
    ddace::EntityArray a;
    a.header.stamp = ros::Time::now();
    a.header.frame_id = frame_id_;
    for (const auto& r : robots_) {
      ddace::Entity e;
      e.name = r->settings().name;
      e.kind = "robot";
      e.pose.x = r->x();
      e.pose.y = r->y();
      e.pose.theta = r->theta();
      e.visible = true;
      e.stale = false;
      e.last_seen = a.header.stamp;
      a.entities.push_back(e);
    }
    entities_pub_.publish(a);
  }

  std::mutex mutex_;
  std::unique_ptr<LinkDirClaim> claim_;  // outlives the robots: their links go first
  std::vector<std::unique_ptr<MockRobot>> robots_;
  std::string frame_id_;
  ros::Publisher state_pub_, entities_pub_;
  ros::Subscriber fault_sub_;
  ros::SteadyTimer state_timer_, entity_timer_;
};

MockHamsterNode::MockHamsterNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

MockHamsterNode::~MockHamsterNode() = default;

void MockHamsterNode::run() {
  impl_->run();
}

}  // namespace ddace::nodes
