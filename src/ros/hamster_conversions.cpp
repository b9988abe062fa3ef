#include "ddace/ros/hamster_conversions.h"

#include "ddace/common/error.h"

namespace ddace::ros_hamster {

ddace::HamsterSensors toSensorsMsg(const hamster::RobotConfig& robot, hamster::Model model,
                                   const hamster::CycleReport& report, SensorMemory& memory) {
  const hamster::Sensors& s = report.sensors;
  if (s.has_light) memory.light = s.light;
  if (s.has_temperature) memory.temperature_c = static_cast<float>(s.temperature_c);
  if (s.has_battery) memory.battery_v = static_cast<float>(s.battery_v);
  ddace::HamsterSensors msg;
  msg.header.frame_id = robot.name;
  msg.robot = robot.name;
  msg.address = robot.address.display();
  msg.model = hamster::modelName(model);
  msg.proximity_left = s.proximity_left;
  msg.proximity_right = s.proximity_right;
  msg.floor_left = s.floor_left;
  msg.floor_right = s.floor_right;
  msg.accel_x = s.accel_x;
  msg.accel_y = s.accel_y;
  msg.accel_z = s.accel_z;
  msg.rssi_dbm = s.rssi_dbm;
  msg.input_a = s.input_a;
  msg.input_b = s.input_b;
  msg.light = memory.light;
  msg.temperature_c = memory.temperature_c;
  msg.battery_v = memory.battery_v;
  msg.pulse_count = s.has_pulse_count ? static_cast<int32_t>(s.pulse_count) : -1;
  msg.left_wheel_sent = report.left_sent;
  msg.right_wheel_sent = report.right_sent;
  msg.command_fresh = report.command_fresh;
  return msg;
}

namespace {

std::array<uint8_t, 3> colour(const std_msgs::ColorRGBA& c, const std::string& field) {
  std::array<uint8_t, 3> out{};
  const float v[3] = {c.r, c.g, c.b};
  const char* names[3] = {"r", "g", "b"};
  for (int i = 0; i < 3; ++i) {
    if (!(v[i] >= 0.0f && v[i] <= 1.0f)) {
      throw Error(field + "." + names[i] + " = " + std::to_string(v[i]) + " is outside 0..1");
    }
    out[i] = static_cast<uint8_t>(std::lround(v[i] * 255.0f));
  }
  return out;
}

}  // namespace

Effects fromEffectsMsg(const ddace::HamsterEffects& msg) {
  Effects e;
  e.left_rgb = colour(msg.left_led, "left_led");
  e.right_rgb = colour(msg.right_led, "right_led");
  if (!(msg.buzzer_hz >= 0.0 && msg.buzzer_hz <= 6500.0)) {
    throw Error("buzzer_hz = " + std::to_string(msg.buzzer_hz) + " is outside 0..6500");
  }
  if (msg.note > 88) throw Error("note = " + std::to_string(msg.note) + " is outside 0..88");
  e.buzzer_hz = msg.buzzer_hz;
  e.note = msg.note;
  return e;
}

}  // namespace ddace::ros_hamster
