#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/yaml_checker.h"
#include "ddace/hamster/config.h"
#include "ddace/hamster/transport.h"

namespace ddace::hamster {

WheelUnits wheelUnitsFromSpeeds(const Calibration& c, double left_mps, double right_mps) {
  if (!std::isfinite(left_mps) || !std::isfinite(right_mps)) {
    throw Error("wheel command is not finite (left_mps=" + std::to_string(left_mps) +
                ", right_mps=" + std::to_string(right_mps) + ")");
  }
  if (!(c.left_mps_per_unit > 0.0) || !(c.right_mps_per_unit > 0.0)) {
    throw Error("speed calibration missing: mps_per_unit must be > 0");
  }
  double left = left_mps / c.left_mps_per_unit;
  double right = right_mps / c.right_mps_per_unit;
  const double limit = std::clamp(c.max_units, 1, kMaxWheelUnits);
  const double largest = std::max(std::fabs(left), std::fabs(right));
  WheelUnits out;
  if (largest > limit + 0.5) {
    // Scale both sides together: the path follower's curvature survives saturation.
    left *= limit / largest;
    right *= limit / largest;
    out.saturated = true;
  }
  out.left =
      static_cast<int8_t>(std::clamp<long>(std::lround(left), -static_cast<long>(limit), static_cast<long>(limit)));
  out.right =
      static_cast<int8_t>(std::clamp<long>(std::lround(right), -static_cast<long>(limit), static_cast<long>(limit)));
  return out;
}

void wheelSpeedsFromTwist(double v_mps, double omega_rps, double track_m, double* left_mps, double* right_mps) {
  *left_mps = v_mps - omega_rps * track_m / 2.0;
  *right_mps = v_mps + omega_rps * track_m / 2.0;
}

namespace {

// A list of device path patterns (`scan`, `port_hints`); replaces `out` entry by entry.
void parsePatterns(YamlChecker& c, const YAML::Node& node, const std::string& what, std::vector<std::string>& out) {
  if (!node.IsSequence()) {
    c.error(node, what + " must be a list of path patterns, e.g. [ttyUSB*]");
    return;
  }
  out.clear();
  for (const auto& item : node) {
    std::string s;
    if (c.scalar(item, what + " entry", s)) out.push_back(s);
  }
}

// `transport:` value; `ble` only in a build with the BLE transport.
bool parseTransport(YamlChecker& c, const YAML::Node& node, const std::string& what, TransportKind& out) {
  std::string t;
  if (!c.scalar(node, what, t)) return false;
  if (t == "serial") {
    out = TransportKind::Serial;
  } else if (t == "ble") {
    if (!bleBuilt()) {
      c.error(node, what +
                        " 'ble': this ddace was built without direct BLE (CMake option DDACE_WITH_BLE=OFF; "
                        "install libsystemd-dev and rebuild, e.g. scripts/setup); use transport: serial (dongle)");
      return false;
    }
    out = TransportKind::Ble;
  } else {
    c.error(node, what + " '" + t + "' is not one of serial, ble");
    return false;
  }
  return true;
}

// A BlueZ adapter name becomes a D-Bus object path element: /org/bluez/<adapter>.
bool parseAdapter(YamlChecker& c, const YAML::Node& node, const std::string& what, std::string& out) {
  std::string a;
  if (!c.scalar(node, what, a)) return false;
  bool ok = !a.empty();
  for (char ch : a) ok = ok && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_');
  if (!ok) {
    c.error(node, what + " '" + a + "' is not a BlueZ adapter name such as hci0 (see bluetoothctl list)");
    return false;
  }
  out = a;
  return true;
}

// An optional integer key in 1..max (a fraction or a word is an error, never truncated).
void positiveInteger(YamlChecker& c, const YAML::Node& node, const std::string& what, int max, int& out) {
  if (node) c.integer(node, what, 1, max, out);
}

// `address_ok` tells whether the robot's address parsed (a bad one is reported here
// and must not be compared with the others).
RobotConfig parseRobot(YamlChecker& c, const YAML::Node& node, size_t index, const RobotConfig& defaults,
                       bool& address_ok) {
  address_ok = false;
  RobotConfig r;
  r.transport = defaults.transport;
  r.ble_adapter = defaults.ble_adapter;
  const std::string where = "robots[" + std::to_string(index) + "]";
  if (!node.IsMap()) {
    c.error(node, where + " must be a mapping with name, address, calibration");
    return r;
  }
  c.onlyKeys(node, {"name", "address", "model", "port_hints", "transport", "ble_adapter", "calibration"}, where);
  const YAML::Node name = c.required(node, "name", where + ": ");
  if (name && c.scalar(name, where + ".name", r.name)) {
    bool ok = !r.name.empty() && (std::isalpha(static_cast<unsigned char>(r.name[0])) != 0);
    for (char ch : r.name) ok = ok && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_');
    if (!ok) c.error(name, where + ".name '" + r.name + "' is not a valid ROS name (letters, digits, _)");
  }
  const std::string who = r.name.empty() ? where : "robot " + r.name;
  std::string address;
  const YAML::Node address_node = c.required(node, "address", who + ": ");
  if (address_node && c.scalar(address_node, who + " address", address)) {
    const auto a = Address::parse(address);
    if (!a) {
      c.error(address_node,
              who + ": address '" + address + "' is neither 12 hex digits (wire order) nor AA:BB:CC:DD:EE:FF");
    } else {
      r.address = *a;
      address_ok = true;
    }
  }
  if (node["model"]) {
    std::string m;
    if (c.scalar(node["model"], who + " model", m)) {
      if (m == "hamster") {
        r.model = Model::Hamster;
      } else if (m == "hamster_s") {
        r.model = Model::HamsterS;
      } else if (m == "auto") {
        r.model = Model::Unknown;
      } else {
        c.error(node["model"], who + ": model '" + m + "' is not one of hamster, hamster_s, auto");
      }
    }
  }
  if (node["port_hints"]) parsePatterns(c, node["port_hints"], who + " port_hints", r.port_hints);
  if (node["transport"]) parseTransport(c, node["transport"], who + " transport", r.transport);
  if (node["ble_adapter"]) parseAdapter(c, node["ble_adapter"], who + " ble_adapter", r.ble_adapter);
  if (r.transport == TransportKind::Ble) {
    if (r.model == Model::HamsterS) {
      c.error(node["model"], who +
                                 ": transport ble drives the original Hamster only (the Hamster-S GATT "
                                 "layout is unknown); reach a Hamster-S through its dongle (transport: serial)");
    }
    r.model = Model::Hamster;  // what the BLE transport reports in its FF reply
    if (node["port_hints"]) {
      c.error(node["port_hints"], who +
                                      ": port_hints apply to transport serial only (a BLE robot is found "
                                      "by its address through BlueZ)");
    }
  } else if (node["ble_adapter"]) {
    c.error(node["ble_adapter"], who + ": ble_adapter applies to transport ble only");
  }
  const YAML::Node cal = c.required(node, "calibration", who + ": ", "measure it with scripts/calibrate_hamster.py");
  if (cal && !cal.IsMap()) {
    c.error(cal, who + " calibration must be a mapping");
  } else if (cal) {
    c.onlyKeys(cal, {"mps_per_unit", "left_mps_per_unit", "right_mps_per_unit", "max_units", "track_m"},
               who + " calibration");
    double both = 0;
    if (cal["mps_per_unit"] && c.positive(cal["mps_per_unit"], who + " calibration.mps_per_unit", both)) {
      r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = both;
    }
    if (cal["left_mps_per_unit"]) {
      c.positive(cal["left_mps_per_unit"], who + " calibration.left_mps_per_unit", r.calibration.left_mps_per_unit);
    }
    if (cal["right_mps_per_unit"]) {
      c.positive(cal["right_mps_per_unit"], who + " calibration.right_mps_per_unit", r.calibration.right_mps_per_unit);
    }
    if (!(r.calibration.left_mps_per_unit > 0) || !(r.calibration.right_mps_per_unit > 0)) {
      c.error(cal, who + " calibration needs mps_per_unit (or left_mps_per_unit and right_mps_per_unit)");
    }
    positiveInteger(c, cal["max_units"], who + " calibration.max_units", kMaxWheelUnits, r.calibration.max_units);
    if (cal["track_m"]) c.positive(cal["track_m"], who + " calibration.track_m", r.calibration.track_m);
  }
  return r;
}

}  // namespace

bool bleBuilt() {
  return DDACE_WITH_BLE != 0;
}

BridgeConfig parseBridgeConfig(const std::string& yaml_text, const std::string& file) {
  YamlChecker c(file);
  const YAML::Node root = c.parse(yaml_text);
  c.throwIfErrors();
  if (!root.IsMap()) throw Error(Diagnostic{file, 1, 1, "the Hamster config must be a mapping with a 'robots' list"});
  BridgeConfig cfg;
  cfg.scan = defaultScanPatterns();
  c.onlyKeys(root,
             {"port_dir", "scan", "rtscts", "command_timeout_s", "command_max_age_s", "link_timeout_s",
              "identify_interval_s", "identify_retries", "rescan_interval_s", "search_quiet_s", "transport",
              "ble_adapter", "ble_connect_timeout_s", "battery_low_v", "battery_empty_v", "battery_samples", "robots"},
             "the Hamster config");
  RobotConfig defaults;  // transport and adapter for robots that do not set their own
  if (root["transport"]) parseTransport(c, root["transport"], "transport", defaults.transport);
  if (root["ble_adapter"]) parseAdapter(c, root["ble_adapter"], "ble_adapter", defaults.ble_adapter);
  if (root["ble_connect_timeout_s"]) {
    c.positive(root["ble_connect_timeout_s"], "ble_connect_timeout_s", cfg.ble_connect_timeout_s);
  }
  if (root["port_dir"]) c.scalar(root["port_dir"], "port_dir", cfg.port_dir);
  if (root["scan"]) parsePatterns(c, root["scan"], "scan", cfg.scan);
  if (root["rtscts"]) c.boolean(root["rtscts"], "rtscts", cfg.rtscts);
  if (root["command_timeout_s"]) c.positive(root["command_timeout_s"], "command_timeout_s", cfg.command_timeout_s);
  if (root["link_timeout_s"]) c.positive(root["link_timeout_s"], "link_timeout_s", cfg.link_timeout_s);
  if (root["identify_interval_s"]) {
    c.positive(root["identify_interval_s"], "identify_interval_s", cfg.identify_interval_s);
  }
  if (root["rescan_interval_s"]) c.positive(root["rescan_interval_s"], "rescan_interval_s", cfg.rescan_interval_s);
  if (root["search_quiet_s"]) c.number(root["search_quiet_s"], "search_quiet_s", 0.0, 600.0, cfg.search_quiet_s);
  if (root["command_max_age_s"]) c.positive(root["command_max_age_s"], "command_max_age_s", cfg.command_max_age_s);
  positiveInteger(c, root["identify_retries"], "identify_retries", 1000, cfg.identify_retries);
  positiveInteger(c, root["battery_samples"], "battery_samples", 1000, cfg.battery_samples);
  if (root["battery_low_v"]) c.positive(root["battery_low_v"], "battery_low_v", cfg.battery_low_v);
  if (root["battery_empty_v"]) c.positive(root["battery_empty_v"], "battery_empty_v", cfg.battery_empty_v);
  if (root["battery_empty_v"] && cfg.battery_empty_v >= cfg.battery_low_v) {
    c.error(root["battery_empty_v"], "battery_empty_v (" + std::to_string(cfg.battery_empty_v) +
                                         ") must be below battery_low_v (" + std::to_string(cfg.battery_low_v) + ")");
  }
  const YAML::Node robots = c.required(root, "robots");
  if (robots && (!robots.IsSequence() || robots.size() == 0)) {
    c.error(robots, "robots must be a non-empty list of {name, address, calibration}");
  } else if (robots) {
    std::map<std::string, size_t> names, addresses;
    for (size_t i = 0; i < robots.size(); ++i) {
      bool address_ok = false;
      RobotConfig r = parseRobot(c, robots[i], i, defaults, address_ok);
      if (!r.name.empty() && !names.emplace(r.name, i).second) {
        c.error(robots[i]["name"], "robot name '" + r.name + "' is used twice");
      }
      if (address_ok && !addresses.emplace(r.address.wire(), i).second) {
        c.error(robots[i]["address"], "address " + r.address.display() + " of robot " + r.name +
                                          " is also used by robots[" + std::to_string(addresses[r.address.wire()]) +
                                          "]");
      }
      cfg.robots.push_back(std::move(r));
    }
  }
  c.throwIfErrors();
  return cfg;
}

BridgeConfig loadBridgeConfig(const std::string& path) {
  return parseBridgeConfig(readTextFile(path), path);
}

std::vector<RobotConfig> selectRobots(const BridgeConfig& config, const std::vector<std::string>& names,
                                      const std::string& what, const std::string& config_file) {
  auto listed = [&](const std::string& name) { return std::find(names.begin(), names.end(), name) != names.end(); };
  for (const auto& name : names) {
    const bool known =
        std::any_of(config.robots.begin(), config.robots.end(), [&](const RobotConfig& r) { return r.name == name; });
    if (!known) throw Error(what + ": robot '" + name + "' is not in " + config_file);
  }
  std::vector<RobotConfig> out;
  for (const auto& r : config.robots)
    if (names.empty() || listed(r.name)) out.push_back(r);
  return out;
}

std::string unusedRobotsWarning(const BridgeConfig& config, const std::vector<std::string>& robots,
                                const std::string& task, const std::string& config_file) {
  std::string others;
  for (const auto& r : config.robots)
    if (std::find(robots.begin(), robots.end(), r.name) == robots.end())
      others += (others.empty() ? "" : ", ") + r.name;
  if (others.empty()) return "";
  return config_file + " also configures " + others + ", which task '" + task +
         "' does not have: not connected (no action needed; remove them from the file to silence this)";
}

}  // namespace ddace::hamster
