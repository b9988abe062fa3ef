// One robot's radio link: find its dongle by address, identify, run the
// response-driven cycle, watch the link and the commands.
//
// Owns: the per-robot state machine used by hamster_bridge_node (and by the
// benchmark and tests without ROS):
//   Searching → (open a candidate port) → Identifying (once the transport is no
//   longer connecting(), send "FF\r", wait for the reply with our address) →
//   Identified (the dongle answered for our robot; every valid sensor line is
//   answered, but only the first one that is answered proves the robot is there) →
//   Streaming (valid sensor lines, each answered with exactly one motoring line) →
//   Lost (no valid line for link_timeout_s, or no answer could be written for that
//   long) → Streaming again when lines come back.
// While Identified or Lost the port stays open and the link waits for lines, as the
// reference clients do: a dongle re-links to its robot by itself, and reopening a
// serial port drops DTR/RTS (HUPCL) every time. Only a hang-up or an I/O error
// closes the port (→ Searching, starting with the port that worked). A direct BLE
// connection has no dongle to re-link it: there, Lost reconnects.
// A robot with transport Ble has one candidate port, bleEndpoint(adapter, address).
// Safety: the wheels sent are the latest command converted with the calibration
// only while that command is younger than command_timeout_s; otherwise zero. A
// command stamped more than command_max_age_s ago (or ahead) is refused. A command
// is never extrapolated. On link loss a zero-wheel line is sent best-effort.
// Reporting: warnings for the user (a port that carries a robot of no configured
// address, a search that found nothing, a missing port directory) are queued for
// takeWarnings(); health() is the diagnostics' level and summary.
// Must not: block (every call returns at once), read a clock (time is passed in),
// or touch ROS.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "ddace/hamster/config.h"
#include "ddace/hamster/protocol.h"
#include "ddace/hamster/transport.h"

namespace ddace::hamster {

/// Ports held by the links of one bridge, so two links never open the same dongle,
/// plus what each port said when it was identified (to try likely ports first).
class PortDirectory {
 public:
  /// False when another link holds the port (canonical path).
  bool claim(const std::string& canonical);
  void release(const std::string& canonical);
  void remember(const std::string& canonical, const Address& address);
  /// The address last identified on this port, if any.
  std::optional<Address> known(const std::string& canonical) const;
  /// True when `message` was never offered, or last reported more than `repeat_s`
  /// before now_s (warnings shared by the links of one bridge: a foreign robot on a
  /// port is reported once per repeat_s, not once per link and scan).
  bool due(const std::string& message, double now_s, double repeat_s);

 private:
  std::set<std::string> claimed_;
  std::vector<std::pair<std::string, Address>> known_;
  std::map<std::string, double> reported_;  // message -> when it was last reported
};

/// The transport factory for one robot: serial ports (with the bridge's rtscts) or,
/// for transport Ble, BlueZ (with ble_connect_timeout_s). Throws ddace::Error for Ble
/// in a build without DDACE_WITH_BLE (the config parser refuses that earlier).
TransportFactory transportFactoryFor(const RobotConfig& robot, const BridgeConfig& bridge);

enum class LinkState {
  Searching,    ///< no port open
  Identifying,  ///< port open, "FF" sent, waiting for the reply with our address
  Identified,   ///< the dongle answered for our robot; no sensor line answered yet
  Streaming,    ///< sensor lines arrive and are answered
  Lost,         ///< was streaming; no valid line (or no answer written) for link_timeout_s
};
/// "searching", "identifying", "identified, no sensor line", "streaming", "lost".
std::string linkStateName(LinkState state);

/// What the diagnostics say about a link (diagnostic_msgs levels OK/WARN/ERROR).
struct LinkHealth {
  enum class Level { Ok, Warn, Error };
  Level level = Level::Error;
  std::string summary;
};

/// Counters since the link object was created.
struct LinkStats {
  uint64_t lines_ok = 0;              ///< valid sensor lines from our robot
  uint64_t lines_dropped = 0;         ///< malformed, wrong packet type, wrong address, overlong
  uint64_t lines_sent = 0;            ///< motoring lines written
  uint64_t write_failures = 0;        ///< motoring lines that could not be written
  uint64_t no_robot_lines = 0;        ///< "dongle without robot" lines
  uint64_t connects = 0;              ///< times the link reached Streaming
  uint64_t link_losses = 0;           ///< times Streaming was left
  uint64_t stale_command_cycles = 0;  ///< cycles answered with zero wheels because no fresh command
  uint64_t saturated_cycles = 0;      ///< cycles whose command exceeded max_units (scaled down)
  uint64_t refused_commands = 0;      ///< wheel commands refused (stale stamp, not finite)
  std::string last_drop_reason;       ///< why the last line was dropped
  std::string last_error;             ///< last port/identification problem
};

/// One decoded sensor line and the wheels sent in reply.
struct CycleReport {
  double time_s = 0.0;  ///< the `now_s` of the poll that received the line
  Sensors sensors;
  int8_t left_sent = 0, right_sent = 0;
  bool command_fresh = false;  ///< the wheels came from a command younger than command_timeout_s
};

class RobotLink {
 public:
  /// A warning that still holds is repeated this often (s): a console scrolls.
  static constexpr double kWarningRepeatS = 10.0;

  RobotLink(RobotConfig robot, const BridgeConfig& bridge, std::shared_ptr<PortDirectory> ports,
            TransportFactory factory);
  ~RobotLink();

  const RobotConfig& robot() const { return robot_; }

  /// Latest wheel ground speeds (m/s) received at now_s. `stamp_age_s` is how old the
  /// command's own stamp is (its sender's clock, seconds; nullopt = unstamped). Throws
  /// ddace::Error (and counts a refused command; the previous command stays and ages
  /// out) for a non-finite speed or a stamp more than command_max_age_s old or ahead.
  void setWheelCommand(double left_mps, double right_mps, double now_s,
                       std::optional<double> stamp_age_s = std::nullopt);
  /// Forgets the command at once (e.g. e-stop): the next cycle sends zero wheels.
  void clearCommand();
  /// LEDs and sound; kept until changed (no timeout: they cannot move the robot).
  void setEffects(const std::array<uint8_t, 3>& left_rgb, const std::array<uint8_t, 3>& right_rgb, double buzzer_hz,
                  uint8_t note);

  /// Does everything that is due at now_s (monotonic seconds): open/identify ports,
  /// read all available bytes, answer each valid sensor line, detect link loss.
  /// Appends one report per valid sensor line to `reports`.
  void poll(double now_s, std::vector<CycleReport>& reports);

  LinkState state() const { return state_; }
  const LinkStats& stats() const { return stats_; }
  /// The port in use (Identifying/Streaming), empty otherwise.
  std::string port() const;
  /// Model reported by the FF reply (Unknown before the first identification).
  Model model() const { return model_; }
  /// Descriptor to wait on with poll(2); -1 when no port is open.
  int fd() const;
  /// Time of the last valid sensor line (monotonic s), negative before the first.
  double lastLineTime() const { return last_line_s_; }
  /// Battery voltage, the mean of the last battery_samples readings; NaN before the first.
  double batteryV() const;
  /// Level and summary for the diagnostics at now_s. `losses_since_report`: link
  /// losses since the previous report (a link that flapped shows even if it is up).
  /// ERROR whenever the robot is not reached (not Streaming) and for an empty battery;
  /// WARN for a low battery or losses since the last report; OK otherwise.
  LinkHealth health(double now_s, uint64_t losses_since_report) const;
  /// Warnings for the user queued since the last call (each one at most every
  /// kWarningRepeatS while it persists).
  std::vector<std::string> takeWarnings();

 private:
  void startSearch(double now_s);
  void tryNextPort(double now_s);
  void closePort(const std::string& why, double now_s, bool restart_search);
  /// Writes zero wheels (other effects kept) to the open transport; errors are ignored.
  void sendStop() noexcept;
  void handleLine(std::string_view line, double now_s, std::vector<CycleReport>& reports);
  void drop(const std::string& why);
  /// The link stopped streaming: zero wheels, then wait on the port (dongle) or reconnect (BLE).
  void loseLink(const std::string& why, double now_s);
  /// A robot at `address` answers on the open port: not ours. Remembers it, warns
  /// when no robot of this bridge has that address, and moves on to the next port.
  void foreignRobot(const Address& address, double now_s);
  void warn(const std::string& message, double now_s);
  /// A warning that the robot is not found (yet): quiet for search_quiet_s of searching.
  void warnSearch(const std::string& message, double now_s);

  RobotConfig robot_;
  BridgeConfig bridge_;
  std::set<std::string> bridge_addresses_;  // wire form of every robot of the bridge
  std::shared_ptr<PortDirectory> ports_;
  TransportFactory factory_;
  std::unique_ptr<Transport> transport_;
  std::string canonical_;
  LineAssembler assembler_;
  LinkState state_ = LinkState::Searching;
  Model model_ = Model::Unknown;
  LinkStats stats_;

  std::vector<std::string> candidates_;
  size_t next_candidate_ = 0;
  std::string preferred_port_;
  double next_search_s_ = 0.0;
  double opened_s_ = 0.0;
  double next_identify_s_ = 0.0;
  int identify_sent_ = 0;
  double last_line_s_ = -1.0;
  double last_write_s_ = -1.0;
  double lost_s_ = -1.0;
  double searching_since_s_ = -1.0;    // since the link last streamed (or began); -1 while it streams
  std::vector<std::string> searched_;  // what each port of the current pass said
  std::vector<std::string> warnings_;
  std::vector<double> battery_;  // last battery_samples readings, V
  size_t battery_next_ = 0;

  bool has_command_ = false;
  double command_left_mps_ = 0.0, command_right_mps_ = 0.0, command_s_ = 0.0;
  Effector effects_;
};

}  // namespace ddace::hamster
