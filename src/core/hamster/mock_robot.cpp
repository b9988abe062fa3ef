#include "ddace/hamster/mock_robot.h"

#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "ddace/common/angle.h"
#include "ddace/common/error.h"
#include "ddace/exec/diff_drive.h"

namespace ddace::hamster {

MockRobotSettings mockSettingsFor(const RobotConfig& robot, size_t index, const std::string& link_dir,
                                  std::optional<double> true_mps_per_unit, double robot_timeout_s) {
  if (true_mps_per_unit && !(*true_mps_per_unit > 0.0))
    throw Error("the true m/s per wheel unit must be > 0 (got " + std::to_string(*true_mps_per_unit) + ")");
  MockRobotSettings s;
  s.name = robot.name;
  s.address = robot.address;
  s.model = robot.model == Model::Unknown ? Model::Hamster : robot.model;
  s.link_path = link_dir + "/hamster_" + robot.name;
  s.left_mps_per_unit = true_mps_per_unit.value_or(robot.calibration.left_mps_per_unit);
  s.right_mps_per_unit = true_mps_per_unit.value_or(robot.calibration.right_mps_per_unit);
  s.track_m = robot.calibration.track_m;
  s.x_m = 0.2 + 0.15 * static_cast<double>(index);
  s.y_m = 0.2;
  s.robot_timeout_s = robot_timeout_s;
  s.seed = static_cast<uint32_t>(index + 1);
  return s;
}

MockFault parseMockFault(const std::string& text) {
  if (text == "none") return MockFault::None;
  if (text == "drop") return MockFault::Drop;
  if (text == "stall") return MockFault::Stall;
  if (text == "garbage") return MockFault::Garbage;
  if (text == "unplug") return MockFault::Unplug;
  throw Error("unknown mock fault '" + text + "' (expected none, drop, stall, garbage or unplug)");
}

std::string mockFaultName(MockFault fault) {
  switch (fault) {
    case MockFault::None:
      return "none";
    case MockFault::Drop:
      return "drop";
    case MockFault::Stall:
      return "stall";
    case MockFault::Garbage:
      return "garbage";
    case MockFault::Unplug:
      return "unplug";
  }
  return "?";
}

MockRobot::MockRobot(MockRobotSettings settings) : settings_(std::move(settings)), rng_(settings_.seed) {
  openPty();
}

MockRobot::~MockRobot() {
  closePty();
  if (!settings_.link_path.empty()) ::unlink(settings_.link_path.c_str());
}

void MockRobot::openPty() {
  termios raw{};
  ::cfmakeraw(&raw);
  ::cfsetispeed(&raw, B115200);
  ::cfsetospeed(&raw, B115200);
  char name[256] = {0};
  if (::openpty(&master_, &slave_, name, &raw, nullptr) != 0) {
    throw Error(std::string("mock Hamster: openpty failed: ") + std::strerror(errno));
  }
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
  ::fcntl(master_, F_SETFD, FD_CLOEXEC);
  ::fcntl(slave_, F_SETFD, FD_CLOEXEC);
  slave_path_ = name;
  assembler_.reset();
  if (!settings_.link_path.empty()) {
    // Replace the symlink atomically, as udev does when a by-id link is re-created.
    const std::string tmp = settings_.link_path + ".new";
    ::unlink(tmp.c_str());
    if (::symlink(slave_path_.c_str(), tmp.c_str()) != 0 || ::rename(tmp.c_str(), settings_.link_path.c_str()) != 0) {
      const std::string why = std::strerror(errno);
      closePty();
      throw Error("mock Hamster: cannot create symlink " + settings_.link_path + ": " + why);
    }
  }
}

void MockRobot::closePty() {
  // The slave stays open in this process while the pty lives, so the master never
  // sees a hang-up when the bridge closes its side; closing both is the "unplug".
  if (master_ >= 0) ::close(master_);
  if (slave_ >= 0) ::close(slave_);
  master_ = slave_ = -1;
}

void MockRobot::send(const std::string& text) {
  if (master_ < 0) return;
  // Nobody reading (bridge not connected): the pty buffer fills and the write fails
  // with EAGAIN, like a dongle talking to nobody. Lines are then simply lost.
  const ssize_t n = ::write(master_, text.data(), text.size());
  (void)n;
}

void MockRobot::setFault(MockFault fault, double duration_s, double now_s) {
  if (fault_ == MockFault::Unplug && fault != MockFault::Unplug && master_ < 0) openPty();
  fault_ = fault;
  fault_end_s_ = now_s + std::max(0.0, duration_s);
  if (fault == MockFault::Unplug) {
    closePty();
    if (!settings_.link_path.empty()) ::unlink(settings_.link_path.c_str());
  }
}

void MockRobot::handleLine(std::string_view line, double now_s) {
  if (line == "FF") {
    ++identify_requests_;
    if (fault_ == MockFault::Drop) return;  // the dongle has no robot to ask
    IdentifyReply reply;
    reply.name = settings_.model == Model::HamsterS ? "HamsterS" : "Hamster";
    reply.model = settings_.model;
    reply.model_code = static_cast<uint8_t>(settings_.model);
    reply.info = "01";
    reply.address = settings_.address;
    send(encodeIdentifyReply(reply) + "\r");
    return;
  }
  if (fault_ == MockFault::Drop) return;
  const ParsedLine parsed = parseLine(line);
  if (parsed.kind != LineKind::Data || parsed.address != settings_.address) {
    ++bad_lines_;
    return;
  }
  const auto e = decodeEffector(settings_.model, parsed.payload);
  if (!e) {
    ++bad_lines_;
    return;
  }
  effector_ = *e;
  ++motoring_lines_;
  last_motoring_s_ = now_s;
}

std::pair<double, double> MockRobot::wheelMps(double now_s) const {
  if (settings_.robot_timeout_s > 0 && now_s - last_motoring_s_ > settings_.robot_timeout_s) return {0.0, 0.0};
  return {effector_.left_wheel * settings_.left_mps_per_unit, effector_.right_wheel * settings_.right_mps_per_unit};
}

void MockRobot::step(double now_s) {
  if (fault_ != MockFault::None && now_s >= fault_end_s_) setFault(MockFault::None, 0.0, now_s);

  // Host → robot.
  if (master_ >= 0) {
    char buf[1024];
    for (;;) {
      const ssize_t n = ::read(master_, buf, sizeof buf);
      if (n <= 0) break;
      assembler_.push(buf, static_cast<size_t>(n), [&](std::string_view line) { handleLine(line, now_s); });
    }
  }

  // The robot moves with the wheels it was last told (unicycle model).
  if (last_step_s_ >= 0.0 && now_s > last_step_s_) {
    const double dt = now_s - last_step_s_;
    const auto [vl, vr] = wheelMps(now_s);
    const double v = 0.5 * (vl + vr), w = (vr - vl) / settings_.track_m;
    const exec::Pose2D p = exec::integrateUnicycle({settings_.x_m, settings_.y_m, settings_.theta_rad}, v, w, dt);
    settings_.x_m = p.x, settings_.y_m = p.y, settings_.theta_rad = p.yaw;
  }
  last_step_s_ = now_s;

  // Robot → host, every sensor period.
  if (next_sensor_s_ < 0.0) next_sensor_s_ = now_s;
  if (now_s < next_sensor_s_) return;
  next_sensor_s_ += settings_.sensor_period_s;
  if (next_sensor_s_ < now_s) next_sensor_s_ = now_s + settings_.sensor_period_s;  // fell behind: no burst
  if (fault_ == MockFault::Unplug || fault_ == MockFault::Stall) return;
  if (fault_ == MockFault::Drop) {
    send("0\r");  // a dongle without a linked robot
    return;
  }
  Sensors s;
  s.model = settings_.model;
  s.proximity_left = 12;
  s.proximity_right = 34;
  s.floor_left = 80;
  s.floor_right = 90;
  s.accel_x = 0;
  s.accel_y = 0;
  s.accel_z = 16384;
  s.rssi_dbm = -55;
  s.input_a = 1;
  s.input_b = 2;
  s.light = 321;
  s.temperature_c = 25.0;
  s.battery_v = settings_.battery_v;
  s.pulse_count = static_cast<uint16_t>(motoring_lines_);
  const std::string line = encodeLine(encodeSensors(settings_.model, s, light_packet_), settings_.address);
  light_packet_ = !light_packet_;
  if (fault_ == MockFault::Garbage) {
    std::uniform_int_distribution<int> byte(0, 255), len(1, 80);
    std::string junk;
    for (int i = 0, n = len(rng_); i < n; ++i) {
      char c = static_cast<char>(byte(rng_));
      junk += c == '\r' || c == '\n' ? 'x' : c;
    }
    send(junk + "\r");
    send(line.substr(0, 20 + len(rng_) % 30) + "\r");  // a truncated line
  }
  send(line);
  ++sensor_lines_;
}

}  // namespace ddace::hamster
