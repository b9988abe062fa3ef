// Conversions between the ROS-free Hamster core (ddace/hamster/*) and ddace messages.
#pragma once

#include <array>
#include <cmath>
#include <string>

#include <ddace/HamsterEffects.h>
#include <ddace/HamsterSensors.h>

#include "ddace/hamster/link.h"

namespace ddace::ros_hamster {

/// Values the robot reports only every other line (light vs temperature + battery);
/// the bridge keeps the latest of each so every message carries them.
struct SensorMemory {
  int32_t light = -1;
  float temperature_c = NAN;
  float battery_v = NAN;
};

/// One cycle's report → message (header.stamp left for the caller). Updates `memory`.
ddace::HamsterSensors toSensorsMsg(const hamster::RobotConfig& robot, hamster::Model model,
                                   const hamster::CycleReport& report, SensorMemory& memory);

/// The LED colours and sound of a HamsterEffects message. Throws ddace::Error naming
/// the field when a value is out of range (colour outside 0..1, buzzer outside
/// 0..6500 Hz or not finite, note above 88).
struct Effects {
  std::array<uint8_t, 3> left_rgb{}, right_rgb{};
  double buzzer_hz = 0.0;
  uint8_t note = 0;
};
Effects fromEffectsMsg(const ddace::HamsterEffects& msg);

}  // namespace ddace::ros_hamster
