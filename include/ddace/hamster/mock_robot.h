// A simulated dongle + Hamster on a pseudo-terminal, speaking the wire protocol.
//
// Owns: one pty pair per simulated robot (the bridge opens the slave side through
// a symlink, exactly as it would open /dev/serial/by-id/...); the robot side of the
// protocol (answers "FF\r", streams sensor lines every sensor_period_s, applies the
// wheel units of every valid motoring line); a unicycle model of the robot driven
// by those units; injectable faults (link drop, one-way stall, garbage, unplug).
// Used by mock_hamster_node, the unit tests and the benchmark. Linux only (openpty).
// Must not: know about ROS, or about the bridge's internals (only the wire).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <utility>

#include "ddace/hamster/config.h"
#include "ddace/hamster/protocol.h"

namespace ddace::hamster {

struct MockRobotSettings {
  std::string name = "R1";
  Address address;
  Model model = Model::Hamster;
  /// Symlink created to the pty slave (parent directory must exist). Empty = none.
  std::string link_path;
  double sensor_period_s = 0.02;  ///< one sensor line every 20 ms (50 Hz)
  /// True wheel speeds per unit (m/s), i.e. what a perfect calibration would find.
  double left_mps_per_unit = 0.002;
  double right_mps_per_unit = 0.002;
  double track_m = 0.033;
  double x_m = 0.0, y_m = 0.0, theta_rad = 0.0;  ///< start pose in the table frame
  double battery_v = 3.9;
  /// The robot stops its wheels when no motoring line came for this long (s); <= 0 =
  /// keep the last wheels forever (the worst case for testing a bridge).
  double robot_timeout_s = 0.0;
  uint32_t seed = 1;  ///< for the garbage generator
};

enum class MockFault {
  None,
  Drop,     ///< radio link gone: no sensor lines, "no robot" lines instead, input ignored
  Stall,    ///< robot→host silent, but motoring lines still reach the robot
  Garbage,  ///< valid lines keep coming, interleaved with random junk and truncated lines
  Unplug,   ///< the pty disappears (master closed), a new one appears when the fault ends
};

/// "none", "drop", "stall", "garbage", "unplug" → MockFault; throws ddace::Error otherwise.
/// The simulated robot standing in for `robot` of the Hamster config, the `index`-th of
/// a row (start pose x = 0.2 + 0.15 * index m, y = 0.2 m; its own garbage seed): its
/// name, address and calibration's track; model Hamster when the config leaves it to
/// auto-detection; its pty linked as <link_dir>/hamster_<name>. The true m/s per wheel
/// unit is `true_mps_per_unit` when given (a calibration to be found), else the
/// config's calibration (a perfectly calibrated robot).
MockRobotSettings mockSettingsFor(const RobotConfig& robot, size_t index, const std::string& link_dir,
                                  std::optional<double> true_mps_per_unit, double robot_timeout_s);

MockFault parseMockFault(const std::string& text);
std::string mockFaultName(MockFault fault);

class MockRobot {
 public:
  /// Opens the pty and creates the symlink. Throws ddace::Error on failure.
  explicit MockRobot(MockRobotSettings settings);
  ~MockRobot();
  MockRobot(const MockRobot&) = delete;
  MockRobot& operator=(const MockRobot&) = delete;

  /// Processes input, emits due sensor lines and integrates the pose up to now_s
  /// (monotonic seconds). Call often (every few ms).
  void step(double now_s);
  /// Starts a fault lasting duration_s (MockFault::None ends any fault now).
  void setFault(MockFault fault, double duration_s, double now_s);
  MockFault fault() const { return fault_; }

  const MockRobotSettings& settings() const { return settings_; }
  /// Path of the pty slave (/dev/pts/N); changes after an unplug.
  std::string slavePath() const { return slave_path_; }
  /// Wheel units of the last valid motoring line (what is on the wire).
  int8_t leftUnits() const { return effector_.left_wheel; }
  int8_t rightUnits() const { return effector_.right_wheel; }
  const Effector& effector() const { return effector_; }
  /// Ground speeds of the wheels at `now_s`, m/s (left, right): the last valid motoring
  /// line's units times the true m/s per unit; zero once robot_timeout_s passed without one.
  std::pair<double, double> wheelMps(double now_s) const;
  /// True while motoring lines arrive (one within the last 100 ms).
  bool driven(double now_s) const { return motoring_lines_ > 0 && now_s - last_motoring_s_ < 0.1; }
  uint64_t motoringLines() const { return motoring_lines_; }
  uint64_t badLines() const { return bad_lines_; }
  uint64_t sensorLines() const { return sensor_lines_; }
  uint64_t identifyRequests() const { return identify_requests_; }
  double x() const { return settings_.x_m; }
  double y() const { return settings_.y_m; }
  double theta() const { return settings_.theta_rad; }

 private:
  void openPty();
  void closePty();
  void send(const std::string& text);
  void handleLine(std::string_view line, double now_s);

  MockRobotSettings settings_;
  int master_ = -1;
  int slave_ = -1;
  std::string slave_path_;
  LineAssembler assembler_;
  Effector effector_;
  MockFault fault_ = MockFault::None;
  double fault_end_s_ = 0.0;
  double next_sensor_s_ = -1.0;
  double last_step_s_ = -1.0;
  double last_motoring_s_ = -1e9;
  uint64_t motoring_lines_ = 0, bad_lines_ = 0, sensor_lines_ = 0, identify_requests_ = 0;
  bool light_packet_ = false;
  std::mt19937 rng_;
};

}  // namespace ddace::hamster
