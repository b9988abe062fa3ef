// rostest: hamster_bridge_node against four mock Hamsters (mock_hamster_node) on
// pseudo-terminals. Checks what is on the wire, not what the bridge says it did.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <ddace/HamsterEffects.h>
#include <ddace/HamsterMockFault.h>
#include <ddace/HamsterMockState.h>
#include <ddace/HamsterSensors.h>
#include <ddace/WheelCommand.h>
#include <diagnostic_msgs/DiagnosticArray.h>

#include "ddace/hamster/config.h"

namespace {

using ddace::hamster::BridgeConfig;

const std::vector<std::string> kRobots = {"R1", "R2", "R3", "R4"};

struct Diag {
  int level = -1;
  std::string message;
  std::map<std::string, std::string> values;
};

/// ROS I/O shared by all tests, created once in main() (subscriptions are not torn
/// down between tests, so no callback can outlive its object).
class World {
 public:
  void start() {
    ros::NodeHandle pnh("~");
    std::string path;
    if (!pnh.getParam("config", path)) throw std::runtime_error("test parameter ~config missing");
    config_ = new BridgeConfig(ddace::hamster::loadBridgeConfig(path));
    ros::NodeHandle nh;
    for (const auto& name : kRobots) {
      wheels_[name] = nh.advertise<ddace::WheelCommand>("/robots/" + name + "/wheels", 1);
      sensor_subs_.push_back(nh.subscribe<ddace::HamsterSensors>("/robots/" + name + "/sensors", 50,
                                                                 [this](const ddace::HamsterSensors::ConstPtr& m) {
                                                                   std::lock_guard<std::mutex> lock(mutex_);
                                                                   sensors_[m->robot] = *m;
                                                                   ++sensor_count_[m->robot];
                                                                 }));
    }
    fault_ = nh.advertise<ddace::HamsterMockFault>("/mock_hamster/fault", 10);
    for (const auto& name : kRobots) {
      effects_[name] = nh.advertise<ddace::HamsterEffects>("/robots/" + name + "/effects", 1, true);
    }
    state_sub_ = nh.subscribe<ddace::HamsterMockState>("/mock_hamster/state", 100,
                                                       [this](const ddace::HamsterMockState::ConstPtr& m) {
                                                         std::lock_guard<std::mutex> lock(mutex_);
                                                         states_[m->robot] = *m;
                                                         seen_[m->robot].insert({m->left_units, m->right_units});
                                                       });
    diag_sub_ = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 50, [this](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          for (const auto& s : m->status) {
            for (const auto& name : kRobots) {
              const std::string suffix = "hamster " + name;
              if (s.name.size() >= suffix.size() &&
                  s.name.compare(s.name.size() - suffix.size(), suffix.size(), suffix) == 0) {
                Diag& d = diags_[name];
                d.level = s.level;
                d.message = s.message;
                for (const auto& kv : s.values) d.values[kv.key] = kv.value;
                if (s.level != diagnostic_msgs::DiagnosticStatus::OK) non_ok_seen_.insert(name);
              }
            }
          }
        });
    commands_ = commands0_;
    running_ = true;
    publisher_ = std::thread([this] {
      ros::WallRate rate(50);
      while (running_ && ros::ok()) {
        std::map<std::string, std::pair<double, double>> cmds;
        {
          std::lock_guard<std::mutex> lock(mutex_);
          cmds = commands_;
        }
        for (const auto& [name, lr] : cmds) {
          ddace::WheelCommand c;
          c.header.stamp = ros::Time::now();
          c.left_mps = lr.first;
          c.right_mps = lr.second;
          wheels_[name].publish(c);
        }
        rate.sleep();
      }
    });
  }

  void stop() {
    running_ = false;
    publisher_.join();
  }

  /// Every robot is commanded at 50 Hz unless a test silences it.
  void commandAll() {
    std::lock_guard<std::mutex> lock(mutex_);
    commands_ = commands0_;
  }

  std::pair<int, int> expected(const std::string& name) {
    for (const auto& r : config_->robots) {
      if (r.name == name) {
        const auto u =
            ddace::hamster::wheelUnitsFromSpeeds(r.calibration, commands0_.at(name).first, commands0_.at(name).second);
        return {u.left, u.right};
      }
    }
    ADD_FAILURE() << "no robot " << name;
    return {0, 0};
  }

  bool wait(const std::function<bool()>& done, double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end && ros::ok()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (done()) return true;
      }
      ros::WallDuration(0.005).sleep();
    }
    return false;
  }

  /// Called with mutex_ held (inside wait()).
  bool onWire(const std::string& name, int left, int right) {
    auto it = states_.find(name);
    return it != states_.end() && it->second.left_units == left && it->second.right_units == right;
  }
  bool allDrivenAsCommanded() {
    for (const auto& name : kRobots) {
      const auto e = expected(name);
      if (!onWire(name, e.first, e.second)) return false;
    }
    return true;
  }
  bool diagLevel(const std::string& name, int level) { return diags_.count(name) && diags_[name].level == level; }
  double diagValue(const std::string& name, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return diags_.count(name) && diags_[name].values.count(key) ? std::stod(diags_[name].values[key]) : -1.0;
  }
  std::string diagText(const std::string& name, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return diags_.count(name) && diags_[name].values.count(key) ? diags_[name].values[key] : "";
  }

  void inject(const std::string& robot, const std::string& fault, double duration_s) {
    ddace::HamsterMockFault f;
    f.robot = robot;
    f.fault = fault;
    f.duration_s = duration_s;
    fault_.publish(f);
  }
  void silence(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    commands_.erase(name);
  }

  static BridgeConfig* config_;
  const std::map<std::string, std::pair<double, double>> commands0_ = {
      {"R1", {0.06, 0.06}}, {"R2", {0.05, -0.05}}, {"R3", {0.3, 0.15}}, {"R4", {-0.036, 0.018}}};
  std::mutex mutex_;
  std::map<std::string, std::pair<double, double>> commands_;
  std::map<std::string, ros::Publisher> wheels_;
  ros::Publisher fault_;
  std::map<std::string, ros::Publisher> effects_;
  ros::Subscriber state_sub_, diag_sub_;
  std::vector<ros::Subscriber> sensor_subs_;
  std::map<std::string, ddace::HamsterMockState> states_;
  std::map<std::string, std::set<std::pair<int, int>>> seen_;  ///< wheel units on the wire, per robot
  std::map<std::string, ddace::HamsterSensors> sensors_;
  std::map<std::string, int> sensor_count_;
  std::map<std::string, Diag> diags_;
  std::set<std::string> non_ok_seen_;
  std::atomic<bool> running_{false};
  std::thread publisher_;
};

BridgeConfig* World::config_ = nullptr;
World* world = nullptr;

class HamsterBridgeTest : public ::testing::Test {
 protected:
  void SetUp() override { world->commandAll(); }
};

/// A node the launch did not name, publishing stamped wheel commands for as long as it
/// lives: `rostopic pub` as /intruder (its own process, so its own caller id).
class Intruder {
 public:
  Intruder(const std::string& robot, double mps) {
    const std::string msg =
        "{header: {stamp: now}, left_mps: " + std::to_string(mps) + ", right_mps: " + std::to_string(mps) + "}";
    pid_ = fork();
    if (pid_ == 0) {
      execlp("rostopic", "rostopic", "pub", "-s", "-r", "20", ("/robots/" + robot + "/wheels").c_str(),
             "ddace/WheelCommand", msg.c_str(), "__name:=intruder", static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~Intruder() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    int status = 0;
    for (int i = 0; i < 100 && waitpid(pid_, &status, WNOHANG) == 0; ++i) ros::WallDuration(0.02).sleep();
    if (waitpid(pid_, &status, WNOHANG) == 0) {  // still there after 2 s
      kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
    }
  }

 private:
  pid_t pid_ = -1;
};

}  // namespace

TEST_F(HamsterBridgeTest, DrivesFourRobotsWithCalibratedWheelUnits) {
  // The expected units come from the core's calibration, and R3's command saturates.
  EXPECT_EQ(world->expected("R1"), std::make_pair(30, 30));
  EXPECT_EQ(world->expected("R2"), std::make_pair(25, -20));
  EXPECT_EQ(world->expected("R3"), std::make_pair(80, 40));
  EXPECT_EQ(world->expected("R4"), std::make_pair(-20, 10));
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0)) << "robots not driven as commanded";
  ASSERT_TRUE(world->wait(
      [&] {
        for (const auto& n : kRobots) {
          if (!world->diagLevel(n, diagnostic_msgs::DiagnosticStatus::OK)) return false;
        }
        return true;
      },
      3.0));
  ros::WallDuration(0.5).sleep();
  std::lock_guard<std::mutex> lock(world->mutex_);
  for (const auto& n : kRobots) {
    EXPECT_EQ(world->states_[n].bad_lines, 0u) << n;
    EXPECT_TRUE(world->states_[n].driven) << n;
    EXPECT_GT(world->sensor_count_[n], 10) << n;
    EXPECT_TRUE(world->sensors_[n].command_fresh) << n;
    EXPECT_NEAR(world->sensors_[n].battery_v, 3.9, 0.011) << n;
    EXPECT_EQ(world->sensors_[n].proximity_right, 34) << n;
  }
  EXPECT_EQ(world->sensors_["R1"].left_wheel_sent, 30);
  EXPECT_EQ(world->sensors_["R4"].model, "hamster_s");
  EXPECT_EQ(world->sensors_["R1"].model, "hamster");
  EXPECT_EQ(world->sensors_["R1"].pulse_count, -1);
  EXPECT_GE(world->sensors_["R4"].pulse_count, 0);
  EXPECT_EQ(world->sensors_["R1"].address, "00:00:00:00:00:A1");
}

TEST_F(HamsterBridgeTest, WatchdogStopsOnlyTheRobotWhoseCommandsStop) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  world->silence("R2");
  const ros::WallTime stop = ros::WallTime::now();
  ASSERT_TRUE(world->wait([&] { return world->onWire("R2", 0, 0); }, 2.0)) << "R2 not stopped by the watchdog";
  const double after_s = (ros::WallTime::now() - stop).toSec();
  EXPECT_GE(after_s, 0.1);  // commands stay valid for command_timeout_s = 0.2 s
  EXPECT_LE(after_s, 1.0);  // generous: the machine may be loaded
  ros::WallDuration(0.3).sleep();
  std::lock_guard<std::mutex> lock(world->mutex_);
  EXPECT_TRUE(world->onWire("R2", 0, 0));
  EXPECT_TRUE(world->states_["R2"].driven);  // the link is alive, it just sends zeros
  EXPECT_FALSE(world->sensors_["R2"].command_fresh);
  EXPECT_TRUE(world->onWire("R1", 30, 30));
}

TEST_F(HamsterBridgeTest, LinkLossZeroesTheWheelsThenTheBridgeReconnects) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    world->non_ok_seen_.clear();
  }
  // Sensor lines stop but the robot still hears the bridge: the bridge's loss handling
  // must reach the robot as zero wheels although commands keep coming.
  world->inject("R3", "stall", 1.5);
  ASSERT_TRUE(world->wait([&] { return world->onWire("R3", 0, 0); }, 1.5)) << "R3 not stopped on link loss";
  ASSERT_TRUE(world->wait([&] { return world->non_ok_seen_.count("R3") > 0; }, 2.0))
      << "diagnostics never showed the loss";
  ASSERT_TRUE(world->wait([&] { return world->onWire("R3", 80, 40) && world->diagLevel("R3", 0); }, 8.0))
      << "R3 not driven again";
  EXPECT_GE(world->diagValue("R3", "link losses"), 1.0);
  std::lock_guard<std::mutex> lock(world->mutex_);
  EXPECT_TRUE(world->onWire("R1", 30, 30));
}

TEST_F(HamsterBridgeTest, RadioDropAndUnplugAreRecovered) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    world->non_ok_seen_.clear();
  }
  world->inject("R1", "drop", 1.0);
  world->inject("R4", "unplug", 1.0);
  ASSERT_TRUE(world->wait([&] { return world->non_ok_seen_.count("R1") && world->non_ok_seen_.count("R4"); }, 3.0));
  ASSERT_TRUE(world->wait(
      [&] { return world->allDrivenAsCommanded() && world->diagLevel("R1", 0) && world->diagLevel("R4", 0); }, 10.0))
      << "not all robots driven again after drop/unplug";
  EXPECT_GE(world->diagValue("R1", "no-robot lines"), 1.0);
  EXPECT_GE(world->diagValue("R4", "link losses"), 1.0);  // the hang-up was noticed
  EXPECT_GE(world->diagValue("R4", "connects"), 2.0);     // and the new pty opened through the symlink
}

TEST_F(HamsterBridgeTest, GarbageAndTruncatedLinesAreCountedAndSurvived) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  const double dropped_before = world->diagValue("R2", "dropped lines");
  const double losses_before = world->diagValue("R2", "link losses");
  int sensors_before = 0;
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    sensors_before = world->sensor_count_["R2"];
  }
  world->inject("R2", "garbage", 1.0);
  ros::WallDuration(1.3).sleep();
  ASSERT_TRUE(world->wait([&] { return world->diagLevel("R2", 0); }, 2.0));
  ros::WallDuration(0.5).sleep();                                             // a fresh diagnostics message
  EXPECT_GE(world->diagValue("R2", "dropped lines") - dropped_before, 40.0);  // 2 bad lines per 20 ms cycle
  EXPECT_EQ(world->diagValue("R2", "link losses"), losses_before);
  std::lock_guard<std::mutex> lock(world->mutex_);
  EXPECT_GE(world->sensor_count_["R2"] - sensors_before, 50);
  EXPECT_TRUE(world->onWire("R2", 25, -20));
  EXPECT_TRUE(world->states_["R2"].driven);
}

TEST_F(HamsterBridgeTest, LedsAndSoundReachTheRobotAndBadValuesAreRefused) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  ddace::HamsterEffects fx;
  fx.left_led.r = 1.0f;   // red
  fx.right_led.g = 0.6f;  // green + blue = cyan on the original Hamster's 8 colours
  fx.right_led.b = 0.8f;
  fx.buzzer_hz = 440.0;
  world->effects_["R1"].publish(fx);
  fx.buzzer_hz = 0.0;
  fx.note = 49;
  world->effects_["R4"].publish(fx);
  auto led = [](const std_msgs::ColorRGBA& c, float r, float g, float b) {
    return std::abs(c.r - r) < 0.01f && std::abs(c.g - g) < 0.01f && std::abs(c.b - b) < 0.01f;
  };
  ASSERT_TRUE(world->wait(
      [&] {
        const auto& r1 = world->states_["R1"];
        const auto& r4 = world->states_["R4"];
        return led(r1.left_led, 1, 0, 0) && led(r1.right_led, 0, 1, 1) && std::abs(r1.buzzer_hz - 440.0) < 1e-6 &&
               led(r4.left_led, 1, 0, 0) && led(r4.right_led, 0, 153 / 255.0f, 204 / 255.0f) && r4.note == 49;
      },
      2.0))
      << "effects not on the wire";
  // Out of range: refused, the previous effects stay.
  ddace::HamsterEffects bad = fx;
  bad.left_led.r = 2.0f;
  bad.note = 0;
  world->effects_["R4"].publish(bad);
  ros::WallDuration(0.3).sleep();
  std::lock_guard<std::mutex> lock(world->mutex_);
  EXPECT_EQ(world->states_["R4"].note, 49);
  EXPECT_TRUE(world->onWire("R1", 30, 30));  // effects never disturb the wheels
}

TEST_F(HamsterBridgeTest, OnlyTheNamedCommandSourcesDriveTheWheelsAndAStrangerIsNamed) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    world->non_ok_seen_.clear();
  }
  // 0.1 m/s is 50 units on R1; the test node, a named source, commands 0.06 m/s (30 units).
  Intruder intruder("R1", 0.1);
  ASSERT_TRUE(world->wait(  // wait() holds the lock: read the values directly
      [&] {
        const auto& v = world->diags_["R1"].values;
        return v.count("foreign commands") && std::stod(v.at("foreign commands")) >= 10.0;
      },
      20.0))
      << "the bridge's diagnostics never counted the intruder's commands";
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    world->seen_["R1"].clear();
  }
  ros::WallDuration(1.0).sleep();  // 20 more of the intruder's commands
  EXPECT_GE(world->diagValue("R1", "foreign commands"), 25.0);
  const std::string foreign = world->diagText("R1", "foreign commands");
  EXPECT_NE(foreign.find(", last from /intruder"), std::string::npos) << foreign;
  EXPECT_EQ(world->diagText("R1", "command sources"), "/hamster_bridge_rostest");
  EXPECT_EQ(world->diagText("R2", "foreign commands"), "0");
  std::lock_guard<std::mutex> lock(world->mutex_);
  const std::set<std::pair<int, int>> follower_only = {{30, 30}};
  EXPECT_EQ(world->seen_["R1"], follower_only) << "the intruder's 50 units reached the wire";
  EXPECT_TRUE(world->non_ok_seen_.count("R1")) << "a foreign publisher left R1's diagnostics OK";
  EXPECT_NE(world->diags_["R1"].message.find("/intruder"), std::string::npos) << world->diags_["R1"].message;
  EXPECT_TRUE(world->onWire("R2", 25, -20));
}

TEST_F(HamsterBridgeTest, AnUnstampedCommandIsRefusedAndTheWatchdogStopsTheRobot) {
  ASSERT_TRUE(world->wait([&] { return world->allDrivenAsCommanded(); }, 20.0));
  world->silence("R1");
  const double unstamped_before = std::max(0.0, world->diagValue("R1", "unstamped commands"));
  {
    std::lock_guard<std::mutex> lock(world->mutex_);
    world->seen_["R1"].clear();
  }
  ddace::WheelCommand c;  // stamp 0: it would skip the age check
  c.left_mps = c.right_mps = 0.08;
  for (int i = 0; i < 50; ++i) {  // 1 s at 50 Hz
    world->wheels_["R1"].publish(c);
    ros::WallDuration(0.02).sleep();
  }
  ASSERT_TRUE(world->wait([&] { return world->onWire("R1", 0, 0); }, 1.0)) << "R1 kept moving on unstamped commands";
  ros::WallDuration(0.3).sleep();  // a fresh diagnostics message
  EXPECT_GE(world->diagValue("R1", "unstamped commands") - unstamped_before, 40.0);
  const std::string unstamped = world->diagText("R1", "unstamped commands");
  EXPECT_NE(unstamped.find(", last from /hamster_bridge_rostest"), std::string::npos) << unstamped;
  std::lock_guard<std::mutex> lock(world->mutex_);
  EXPECT_EQ(world->seen_["R1"].count({40, 40}), 0u) << "an unstamped command reached the wire";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hamster_bridge_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  World w;
  w.start();
  world = &w;
  const int result = RUN_ALL_TESTS();
  w.stop();
  spinner.stop();
  return result;
}
