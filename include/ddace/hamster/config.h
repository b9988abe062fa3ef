// Which Hamster is which, where to look for its dongle, and how fast its wheels go.
//
// Owns: the bridge configuration (config/hamsters.yaml) and the speed calibration
// that turns wheel ground speeds (m/s) into the robot's open-loop wheel units.
// Must not: open ports or talk to ROS.
#pragma once

#include <string>
#include <vector>

#include "ddace/hamster/protocol.h"

namespace ddace::hamster {

/// Linear wheel model per robot: ground speed = units * mps_per_unit (per side).
/// Measure it with scripts/calibrate_hamster.py.
struct Calibration {
  double left_mps_per_unit = 0.0;   ///< m/s of the left wheel per wheel unit (> 0)
  double right_mps_per_unit = 0.0;  ///< m/s of the right wheel per wheel unit (> 0)
  int max_units = kMaxWheelUnits;   ///< largest |units| sent, 1..100
  double track_m = 0.033;           ///< distance between the wheel contact points, m (for rad/s)
};

/// Result of converting one wheel command.
struct WheelUnits {
  int8_t left = 0;
  int8_t right = 0;
  bool saturated = false;  ///< both sides were scaled down to stay within max_units
};

/// m/s per wheel → units. When either side exceeds max_units both are scaled by the
/// same factor, so the commanded curvature is kept. Throws ddace::Error when a speed
/// is not finite (never turned into motion).
WheelUnits wheelUnitsFromSpeeds(const Calibration& calibration, double left_mps, double right_mps);

/// Forward speed v (m/s) and yaw rate omega (rad/s, counter-clockwise) → wheel
/// ground speeds (left, right) for a differential drive with the given track.
void wheelSpeedsFromTwist(double v_mps, double omega_rps, double track_m, double* left_mps, double* right_mps);

/// How the host reaches a robot.
enum class TransportKind {
  Serial,  ///< its USB radio dongle (a serial port found by address)
  Ble,     ///< directly over Bluetooth LE through BlueZ (original Hamster only; needs DDACE_WITH_BLE)
};

struct RobotConfig {
  std::string name;                     ///< ROS name, e.g. "R1" (topics /robots/R1/...)
  Address address;                      ///< radio address (wire order)
  Model model = Model::Unknown;         ///< Unknown = accept what the FF reply says (always Hamster for BLE)
  std::vector<std::string> port_hints;  ///< glob patterns tried first (relative to port_dir); serial only
  TransportKind transport = TransportKind::Serial;
  std::string ble_adapter = "hci0";  ///< BlueZ adapter (BLE only), e.g. hci0
  Calibration calibration;
};

struct BridgeConfig {
  std::string port_dir = "/dev";     ///< base of relative port patterns
  std::vector<std::string> scan;     ///< patterns scanned after the hints
  bool rtscts = true;                ///< RTS/CTS hardware flow control
  double command_timeout_s = 0.2;    ///< no command for this long → zero wheels
  double command_max_age_s = 0.2;    ///< a command stamped longer ago (or ahead) is refused
  double link_timeout_s = 0.25;      ///< no valid line for this long → reconnect
  double identify_interval_s = 0.1;  ///< between FF requests
  int identify_retries = 10;         ///< FF requests per port before giving up on it
  double rescan_interval_s = 0.5;    ///< pause after every port was tried
  /// A robot not found is reported once it has been searched for this long (s): robots
  /// being switched on and a rehearsal's mock links come up while the bridge starts.
  double search_quiet_s = 3.0;
  double ble_connect_timeout_s = 20.0;  ///< BLE: give up a connection attempt after this long
  double battery_low_v = 3.6;           ///< mean battery below this → WARN (roboid's "low")
  double battery_empty_v = 3.0;         ///< mean battery below this → ERROR (roboid's "empty")
  int battery_samples = 10;             ///< readings averaged for the battery state
  std::vector<RobotConfig> robots;
};

/// Whether this build has the direct-BLE transport (CMake option DDACE_WITH_BLE).
bool bleBuilt();

/// Parses config/hamsters.yaml text. `file` names the source in errors. Throws
/// ddace::Error with file:line:column for every problem found (unknown keys, bad
/// addresses, duplicate names or addresses, missing or non-positive calibration,
/// `transport: ble` in a build without BLE or for a Hamster-S).
BridgeConfig parseBridgeConfig(const std::string& yaml_text, const std::string& file);

/// Reads and parses a file (error naming the path when it cannot be read).
BridgeConfig loadBridgeConfig(const std::string& path);

/// The robots of `config` that `names` lists (every robot when `names` is empty), in the
/// config's order. A name the config does not have is an error, not a robot silently
/// left out: ddace::Error "<what>: robot 'X' is not in <config_file>".
std::vector<RobotConfig> selectRobots(const BridgeConfig& config, const std::vector<std::string>& names,
                                      const std::string& what, const std::string& config_file);

/// The warning for a bridge given a task: the configured robots that the task's `robots` do
/// not list, which are not connected -- so a config of another task never goes unnoticed:
/// "<config_file> also configures R3, R4, which task '<task>' does not have: not connected
/// (no action needed; ...)". "" when the config has no other robot.
std::string unusedRobotsWarning(const BridgeConfig& config, const std::vector<std::string>& robots,
                                const std::string& task, const std::string& config_file);

}  // namespace ddace::hamster
