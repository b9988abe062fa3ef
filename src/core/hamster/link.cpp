#include "ddace/hamster/link.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <utility>

#include "ddace/common/error.h"
#if DDACE_WITH_BLE
#include "ddace/hamster/ble_transport.h"
#endif

namespace ddace::hamster {

bool PortDirectory::claim(const std::string& canonical) {
  return claimed_.insert(canonical).second;
}

void PortDirectory::release(const std::string& canonical) {
  claimed_.erase(canonical);
}

void PortDirectory::remember(const std::string& canonical, const Address& address) {
  for (auto& [port, a] : known_) {
    if (port == canonical) {
      a = address;
      return;
    }
  }
  known_.emplace_back(canonical, address);
}

bool PortDirectory::due(const std::string& message, double now_s, double repeat_s) {
  const auto it = reported_.find(message);
  if (it != reported_.end() && now_s - it->second < repeat_s) return false;
  reported_[message] = now_s;
  return true;
}

std::optional<Address> PortDirectory::known(const std::string& canonical) const {
  for (const auto& [port, a] : known_) {
    if (port == canonical) return a;
  }
  return std::nullopt;
}

TransportFactory transportFactoryFor(const RobotConfig& robot, const BridgeConfig& bridge) {
  if (robot.transport == TransportKind::Serial) return serialTransportFactory(bridge.rtscts);
#if DDACE_WITH_BLE
  return bleTransportFactory(bridge.ble_connect_timeout_s);
#else
  throw Error("robot " + robot.name + ": transport ble, but this ddace was built without BLE (DDACE_WITH_BLE=OFF)");
#endif
}

std::string linkStateName(LinkState state) {
  switch (state) {
    case LinkState::Searching:
      return "searching";
    case LinkState::Identifying:
      return "identifying";
    case LinkState::Identified:
      return "identified, no sensor line";
    case LinkState::Streaming:
      return "streaming";
    case LinkState::Lost:
      return "lost";
  }
  return "?";
}

RobotLink::RobotLink(RobotConfig robot, const BridgeConfig& bridge, std::shared_ptr<PortDirectory> ports,
                     TransportFactory factory)
    : robot_(std::move(robot)), bridge_(bridge), ports_(std::move(ports)), factory_(std::move(factory)) {
  for (const auto& r : bridge_.robots) bridge_addresses_.insert(r.address.wire());
  bridge_addresses_.insert(robot_.address.wire());
  bridge_.robots.clear();
  model_ = robot_.model;
}

RobotLink::~RobotLink() {
  if (transport_ && (state_ == LinkState::Streaming || state_ == LinkState::Lost)) sendStop();  // leave it standing
  if (transport_) transport_->close();
  if (!canonical_.empty()) ports_->release(canonical_);
}

void RobotLink::sendStop() noexcept {
  // Best effort: the link may already be gone.
  try {
    Effector zero = effects_;
    zero.left_wheel = zero.right_wheel = 0;
    const std::string line = encodeLine(encodeEffector(model_, zero), robot_.address);
    transport_->write(line.data(), line.size());
  } catch (const std::exception&) {
  }
}

void RobotLink::setWheelCommand(double left_mps, double right_mps, double now_s, std::optional<double> stamp_age_s) {
  // Validates (throws on NaN/inf, missing calibration, a stale stamp) before replacing the command.
  try {
    if (stamp_age_s && !(std::abs(*stamp_age_s) <= bridge_.command_max_age_s)) {
      char why[160];
      std::snprintf(why, sizeof why, "command stamped %.3f s %s (more than command_max_age_s %.3f s)",
                    std::abs(*stamp_age_s), *stamp_age_s >= 0 ? "ago" : "in the future", bridge_.command_max_age_s);
      throw Error(why);
    }
    wheelUnitsFromSpeeds(robot_.calibration, left_mps, right_mps);
  } catch (const Error&) {
    ++stats_.refused_commands;
    throw;
  }
  command_left_mps_ = left_mps;
  command_right_mps_ = right_mps;
  command_s_ = now_s;
  has_command_ = true;
}

void RobotLink::clearCommand() {
  has_command_ = false;
}

void RobotLink::setEffects(const std::array<uint8_t, 3>& left_rgb, const std::array<uint8_t, 3>& right_rgb,
                           double buzzer_hz, uint8_t note) {
  effects_.left_led_rgb = left_rgb;
  effects_.right_led_rgb = right_rgb;
  effects_.buzzer_hz = std::isfinite(buzzer_hz) ? buzzer_hz : 0.0;
  effects_.note = note;
}

std::string RobotLink::port() const {
  return transport_ ? transport_->name() : std::string();
}

int RobotLink::fd() const {
  return transport_ ? transport_->fd() : -1;
}

void RobotLink::warn(const std::string& message, double now_s) {
  if (ports_->due(robot_.name + ": " + message, now_s, kWarningRepeatS)) warnings_.push_back(message);
}

void RobotLink::warnSearch(const std::string& message, double now_s) {
  if (now_s - searching_since_s_ >= bridge_.search_quiet_s) warn(message, now_s);
}

std::vector<std::string> RobotLink::takeWarnings() {
  return std::exchange(warnings_, {});
}

double RobotLink::batteryV() const {
  if (battery_.empty()) return std::nan("");
  return std::accumulate(battery_.begin(), battery_.end(), 0.0) / static_cast<double>(battery_.size());
}

LinkHealth RobotLink::health(double now_s, uint64_t losses_since_report) const {
  using Level = LinkHealth::Level;
  const std::string why = stats_.last_error.empty() ? std::string() : ": " + stats_.last_error;
  char buf[256];
  switch (state_) {
    case LinkState::Searching:
      return {Level::Error, "robot unreachable, no port (wheels not driven)" + why};
    case LinkState::Identifying:
      return {Level::Error, "robot unreachable, identifying on " + port()};
    case LinkState::Identified:
      return {Level::Error, "robot unreachable: the dongle on " + port() +
                                " answers for it but no sensor line came (robot off or out of range?)"};
    case LinkState::Lost:
      std::snprintf(buf, sizeof buf, "robot unreachable for %.1f s, waiting on %s (wheels zeroed)", now_s - lost_s_,
                    port().c_str());
      return {Level::Error, buf + why};
    case LinkState::Streaming:
      break;
  }
  const double v = batteryV();
  if (v < bridge_.battery_empty_v) {
    std::snprintf(buf, sizeof buf, "streaming, battery empty (%.2f V < %.2f V)", v, bridge_.battery_empty_v);
    return {Level::Error, buf};
  }
  if (losses_since_report > 0) {
    std::snprintf(buf, sizeof buf, "streaming, but the link was lost %llu times since the last report",
                  static_cast<unsigned long long>(losses_since_report));
    return {Level::Warn, buf};
  }
  if (v < bridge_.battery_low_v) {
    std::snprintf(buf, sizeof buf, "streaming, battery low (%.2f V < %.2f V)", v, bridge_.battery_low_v);
    return {Level::Warn, buf};
  }
  return {Level::Ok, "streaming"};
}

void RobotLink::drop(const std::string& why) {
  ++stats_.lines_dropped;
  stats_.last_drop_reason = why;
}

void RobotLink::startSearch(double now_s) {
  if (searching_since_s_ < 0) searching_since_s_ = now_s;
  if (robot_.transport == TransportKind::Ble) {
    // One endpoint, named by adapter and address: the robot is found by BlueZ.
    candidates_ = {bleEndpoint(robot_.ble_adapter, robot_.address)};
    next_candidate_ = 0;
    next_search_s_ = now_s;
    return;
  }
  std::error_code ec;
  if (!std::filesystem::is_directory(bridge_.port_dir.empty() ? "/dev" : bridge_.port_dir, ec)) {
    stats_.last_error = "port directory " + bridge_.port_dir + " does not exist";
    warnSearch(stats_.last_error + ": set port_dir in the config or ~port_dir (still looking)", now_s);
  }
  std::vector<std::string> patterns = robot_.port_hints;
  candidates_ = expandPorts(patterns, bridge_.port_dir);
  const size_t hinted = candidates_.size();
  for (const auto& p : expandPorts(bridge_.scan, bridge_.port_dir)) {
    if (std::find(candidates_.begin(), candidates_.end(), p) == candidates_.end()) candidates_.push_back(p);
  }
  // Order: the port that worked last, then hinted ports, then ports whose last
  // identification showed our address, then unknown ports; ports known to carry
  // another robot go last (robots can be swapped between dongles).
  auto rank = [&](const std::string& p, size_t index) {
    if (!preferred_port_.empty() && p == preferred_port_) return 0;
    const auto known = ports_->known(canonicalPort(p));
    if (known && *known == robot_.address) return 1;
    if (index < hinted) return 2;
    if (!known) return 3;
    return 4;
  };
  std::vector<std::pair<int, size_t>> order;
  for (size_t i = 0; i < candidates_.size(); ++i) order.emplace_back(rank(candidates_[i], i), i);
  std::stable_sort(order.begin(), order.end());
  std::vector<std::string> sorted;
  for (const auto& [r, i] : order) sorted.push_back(candidates_[i]);
  candidates_ = std::move(sorted);
  next_candidate_ = 0;
  next_search_s_ = now_s;
  searched_.clear();
}

void RobotLink::tryNextPort(double now_s) {
  while (next_candidate_ < candidates_.size()) {
    const std::string path = candidates_[next_candidate_++];
    const std::string canonical = canonicalPort(path);
    if (!ports_->claim(canonical)) {  // another robot's link holds it
      searched_.push_back(path + " (held by another robot of this bridge)");
      continue;
    }
    auto transport = factory_(path);
    try {
      transport->open();
    } catch (const Error& e) {
      ports_->release(canonical);
      stats_.last_error = e.what();
      searched_.push_back(path + " (" + e.what() + ")");
      continue;
    }
    transport_ = std::move(transport);
    canonical_ = canonical;
    assembler_.reset();
    state_ = LinkState::Identifying;
    opened_s_ = now_s;
    next_identify_s_ = now_s;
    identify_sent_ = 0;
    return;
  }
  // Every candidate tried: say where we looked, then wait before scanning again
  // (ports may appear later).
  std::string where;
  for (const auto& s : searched_) where += (where.empty() ? "" : "; ") + s;
  if (searched_.empty()) {
    std::string patterns;
    for (const auto& p : robot_.port_hints) patterns += (patterns.empty() ? "" : ", ") + p;
    for (const auto& p : bridge_.scan) patterns += (patterns.empty() ? "" : ", ") + p;
    stats_.last_error = "no port matches [" + patterns + "] under " + bridge_.port_dir;
  } else {
    stats_.last_error = "not found on " + std::to_string(searched_.size()) + " ports searched: " + where;
  }
  warnSearch("robot " + robot_.address.display() + " " + stats_.last_error +
                 " (still looking; if the robot is on, check its address and port_hints in the config)",
             now_s);
  startSearch(now_s);
  next_search_s_ = now_s + bridge_.rescan_interval_s;
}

void RobotLink::loseLink(const std::string& why, double now_s) {
  if (robot_.transport == TransportKind::Ble) {
    closePort(why, now_s, true);  // counts the loss and sends the zero line
    return;
  }
  ++stats_.link_losses;
  sendStop();  // if the radio still reaches the robot
  stats_.last_error = why;
  state_ = LinkState::Lost;
  lost_s_ = now_s;
}

void RobotLink::foreignRobot(const Address& address, double now_s) {
  ports_->remember(canonical_, address);
  if (!bridge_addresses_.count(address.wire()))
    warn("port " + port() + " carries robot " + address.display() +
             ", which is not in the config (no robot of this bridge has that address)",
         now_s);
  closePort("robot " + address.display() + " answers there", now_s, false);
}

void RobotLink::closePort(const std::string& why, double now_s, bool restart_search) {
  if (state_ == LinkState::Streaming) {
    ++stats_.link_losses;
    sendStop();  // if the radio still reaches the robot
  } else if (state_ == LinkState::Lost) {
    sendStop();
  }
  if (transport_ && !restart_search) searched_.push_back(port() + " (" + why + ")");  // for the search report
  if (transport_) transport_->close();
  transport_.reset();
  if (!canonical_.empty()) ports_->release(canonical_);
  canonical_.clear();
  stats_.last_error = why;
  state_ = LinkState::Searching;
  if (restart_search) {
    startSearch(now_s);  // the port that worked comes first
    // Reopening flushes the port: give the zero-wheel line time to leave first
    // (54 bytes take 5 ms at 115200 baud).
    next_search_s_ = now_s + 0.05;
  } else {
    next_search_s_ = now_s;  // go on with the next candidate
  }
}

void RobotLink::handleLine(std::string_view line, double now_s, std::vector<CycleReport>& reports) {
  const ParsedLine parsed = parseLine(line);
  switch (parsed.kind) {
    case LineKind::Malformed:
      drop(parsed.error);
      return;
    case LineKind::NoRobot:
      ++stats_.no_robot_lines;
      if (state_ == LinkState::Identifying) stats_.last_error = "dongle on " + port() + " has no robot linked";
      return;
    case LineKind::Identify:
      if (state_ != LinkState::Identifying) return;  // a late reply to an earlier FF
      if (parsed.identify.address != robot_.address) {
        foreignRobot(parsed.identify.address, now_s);
        return;
      }
      ports_->remember(canonical_, parsed.identify.address);
      if (parsed.identify.model != Model::Hamster && parsed.identify.model != Model::HamsterS) {
        closePort("robot on " + port() + " reports model code " + std::to_string(parsed.identify.model_code) +
                      ", which is not a Hamster (04) or Hamster-S (0E)",
                  now_s, false);
        return;
      }
      if (robot_.model != Model::Unknown && parsed.identify.model != robot_.model) {
        closePort("robot " + robot_.address.display() + " is a " + modelName(parsed.identify.model) +
                      " but the config says " + modelName(robot_.model),
                  now_s, false);
        return;
      }
      model_ = parsed.identify.model;
      preferred_port_ = port();
      // Our dongle, but the robot is proven there only by its first sensor line.
      state_ = LinkState::Identified;
      stats_.last_error.clear();
      return;
    case LineKind::Data:
      break;
  }
  if (parsed.address != robot_.address) {
    if (state_ == LinkState::Identifying || state_ == LinkState::Identified || state_ == LinkState::Lost) {
      // The dongle streams another robot's lines (it re-linked, or it never was ours).
      foreignRobot(parsed.address, now_s);
      return;
    }
    drop("line from foreign address " + parsed.address.display());
    return;
  }
  if (state_ == LinkState::Identifying) return;  // ours, but not identified yet
  std::string why;
  const auto sensors = decodeSensors(model_, parsed.payload, &why);
  if (!sensors) {
    drop(why);
    return;
  }
  last_line_s_ = now_s;
  ++stats_.lines_ok;
  if (sensors->has_battery && std::isfinite(sensors->battery_v)) {
    const size_t n = static_cast<size_t>(std::max(1, bridge_.battery_samples));
    if (battery_.size() < n) {
      battery_.push_back(sensors->battery_v);
    } else {
      battery_[battery_next_ % n] = sensors->battery_v;
    }
    battery_next_ = (battery_next_ + 1) % n;
  }
  CycleReport report;
  report.time_s = now_s;
  report.sensors = *sensors;
  Effector effector = effects_;
  report.command_fresh = has_command_ && now_s - command_s_ <= bridge_.command_timeout_s && now_s >= command_s_;
  if (report.command_fresh) {
    const WheelUnits u = wheelUnitsFromSpeeds(robot_.calibration, command_left_mps_, command_right_mps_);
    effector.left_wheel = u.left;
    effector.right_wheel = u.right;
    if (u.saturated) ++stats_.saturated_cycles;
  } else {
    ++stats_.stale_command_cycles;
  }
  report.left_sent = effector.left_wheel;
  report.right_sent = effector.right_wheel;
  const std::string out = encodeLine(encodeEffector(model_, effector), robot_.address);
  try {
    transport_->write(out.data(), out.size());
    ++stats_.lines_sent;
    last_write_s_ = now_s;
    if (state_ != LinkState::Streaming) {
      // A sensor line answered: the robot hears us and we hear it.
      state_ = LinkState::Streaming;
      searching_since_s_ = -1.0;
      ++stats_.connects;
      stats_.last_error.clear();
    }
  } catch (const Error& e) {
    ++stats_.write_failures;
    stats_.last_error = e.what();
  }
  reports.push_back(report);
}

void RobotLink::poll(double now_s, std::vector<CycleReport>& reports) {
  if (state_ == LinkState::Searching) {
    if (candidates_.empty() && next_candidate_ == 0 && now_s >= next_search_s_) startSearch(now_s);
    if (now_s >= next_search_s_) tryNextPort(now_s);
    if (state_ == LinkState::Searching) return;
  }
  char buf[1024];
  for (int rounds = 0; rounds < 64 && transport_; ++rounds) {
    size_t n = 0;
    try {
      n = transport_->read(buf, sizeof buf);
    } catch (const Error& e) {
      // A hang-up or an I/O error: the only reasons to let go of an identified port.
      const bool ours = state_ == LinkState::Streaming || state_ == LinkState::Lost || state_ == LinkState::Identified;
      closePort(e.what(), now_s, ours);
      return;
    }
    if (n == 0) break;
    const uint64_t overlong_before = assembler_.overlong();
    assembler_.push(buf, n, [&](std::string_view line) {
      if (transport_) handleLine(line, now_s, reports);
    });
    if (assembler_.overlong() != overlong_before) {
      stats_.lines_dropped += assembler_.overlong() - overlong_before;
      stats_.last_drop_reason = "line longer than " + std::to_string(kMaxLineChars) + " characters";
    }
  }
  if (!transport_) return;
  if (state_ == LinkState::Identifying) {
    // A BLE connection in progress takes seconds: ask FF only once it stands (the
    // transport throws from read() when it gives up).
    if (now_s >= next_identify_s_ && !transport_->connecting()) {
      if (identify_sent_ >= bridge_.identify_retries) {
        closePort("no FF reply from " + port() + " after " + std::to_string(identify_sent_) + " requests", now_s,
                  false);
        return;
      }
      try {
        transport_->write(kIdentifyRequest.data(), kIdentifyRequest.size());
      } catch (const Error& e) {
        closePort(e.what(), now_s, false);
        return;
      }
      ++identify_sent_;
      next_identify_s_ = now_s + bridge_.identify_interval_s;
    }
  } else if (state_ == LinkState::Streaming && now_s - last_line_s_ > bridge_.link_timeout_s) {
    char why[160];
    std::snprintf(why, sizeof why, "no valid line from %s for %.2f s", robot_.address.display().c_str(),
                  bridge_.link_timeout_s);
    loseLink(why, now_s);
  } else if (state_ == LinkState::Streaming && now_s - last_write_s_ > bridge_.link_timeout_s) {
    // Lines come in but none of our answers goes out (e.g. CTS never asserted): the
    // robot keeps its last command, so this is a lost link too.
    char why[96];
    std::snprintf(why, sizeof why, "no motoring line could be written for %.2f s (", bridge_.link_timeout_s);
    loseLink(why + stats_.last_error + ")", now_s);
  }
}

}  // namespace ddace::hamster
