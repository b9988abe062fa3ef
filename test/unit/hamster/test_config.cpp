// config/hamsters.yaml parsing and the m/s → wheel-unit calibration.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <regex>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/hamster/config.h"
#include "ddace/hamster/mock_robot.h"
#include "ddace/hamster/transport.h"

#include "../common/error_of.h"

using namespace ddace::hamster;

namespace {

/// What parseBridgeConfig says of `yaml` as h.yaml ("" when it accepts it).
std::string errorOf(const std::string& yaml) {
  return ddace::test::errorOf([&] { parseBridgeConfig(yaml, "h.yaml"); });
}

const char* kRobot = "robots:\n  - name: R1\n    address: 67E1A48B4BD9\n    calibration: {mps_per_unit: 0.002}\n";

}  // namespace

TEST(HamsterConfig, ParsesRobotsAndDefaults) {
  const BridgeConfig c = parseBridgeConfig(
      "port_dir: /tmp/x\nscan: []\nlink_timeout_s: 0.3\nrobots:\n"
      "  - name: R1\n    address: D9:4B:8B:A4:E1:67\n    model: hamster_s\n    port_hints: [hamster_R1, /abs/*]\n"
      "    calibration: {left_mps_per_unit: 0.002, right_mps_per_unit: 0.0021, max_units: 80, track_m: 0.034}\n"
      "  - name: R2\n    address: '000000000001'\n    calibration: {mps_per_unit: 0.0019}\n",
      "h.yaml");
  EXPECT_EQ(c.port_dir, "/tmp/x");
  EXPECT_TRUE(c.scan.empty());
  EXPECT_DOUBLE_EQ(c.link_timeout_s, 0.3);
  EXPECT_DOUBLE_EQ(c.command_timeout_s, 0.2);
  ASSERT_EQ(c.robots.size(), 2u);
  EXPECT_EQ(c.robots[0].address.wire(), "67E1A48B4BD9");
  EXPECT_EQ(c.robots[0].model, Model::HamsterS);
  EXPECT_EQ(c.robots[0].port_hints, (std::vector<std::string>{"hamster_R1", "/abs/*"}));
  EXPECT_DOUBLE_EQ(c.robots[0].calibration.right_mps_per_unit, 0.0021);
  EXPECT_EQ(c.robots[0].calibration.max_units, 80);
  EXPECT_EQ(c.robots[1].model, Model::Unknown);
  EXPECT_DOUBLE_EQ(c.robots[1].calibration.left_mps_per_unit, 0.0019);
  EXPECT_DOUBLE_EQ(c.robots[1].calibration.right_mps_per_unit, 0.0019);
  // Without a scan key the usual device patterns are scanned.
  EXPECT_EQ(parseBridgeConfig(kRobot, "h.yaml").scan.size(), 3u);
}

TEST(HamsterConfig, ShippedConfigIsValid) {
  const BridgeConfig c =
      loadBridgeConfig((ddace::findRepository("", {"config/hamsters.yaml"}) / "config/hamsters.yaml").string());
  EXPECT_GE(c.robots.size(), 1u);
}

// The header comment of config/hamsters.yaml is the reference users read for what an
// omitted key means: "key: type  text ... (default V" (the text may go on over indented
// lines). Every default it states must be the one the parser applies.
TEST(HamsterConfig, TheShippedConfigStatesTheDefaultsTheParserApplies) {
  const std::string file = (ddace::findRepository("", {"config/hamsters.yaml"}) / "config/hamsters.yaml").string();
  std::map<std::string, std::string> documented;  // key -> its "(default ...)" text
  const std::regex key_line(R"(^#( {3}| {5}- | {7}| {9})([a-z_]+):)");
  const std::regex default_text(R"(\(default (\[[^\]]*\]|[^,;)]+))");
  std::istringstream lines(ddace::readTextFile(file));
  std::string key;
  for (std::string line; std::getline(lines, line);) {
    std::smatch m;
    if (line.rfind("#  ", 0) != 0) {
      key.clear();  // the end of the schema block
      continue;
    }
    if (std::regex_search(line, m, key_line)) key = m[2].str();
    if (!key.empty() && !documented.count(key) && std::regex_search(line, m, default_text))
      documented[key] = m[1].str();
  }
  const BridgeConfig c;
  const RobotConfig r;
  const Calibration cal;
  auto number = [](double v) {
    std::ostringstream out;
    out.precision(17);  // round-trips: compared as a number below
    out << v;
    return out.str();
  };
  std::string scan;
  for (const auto& p : defaultScanPatterns()) scan += (scan.empty() ? "" : ", ") + p;
  const std::map<std::string, std::string> applied = {
      {"port_dir", c.port_dir},
      {"scan", "[" + scan + "]"},
      {"rtscts", c.rtscts ? "true" : "false"},
      {"command_timeout_s", number(c.command_timeout_s)},
      {"command_max_age_s", number(c.command_max_age_s)},
      {"link_timeout_s", number(c.link_timeout_s)},
      {"identify_interval_s", number(c.identify_interval_s)},
      {"identify_retries", number(c.identify_retries)},
      {"rescan_interval_s", number(c.rescan_interval_s)},
      {"search_quiet_s", number(c.search_quiet_s)},
      {"transport", r.transport == TransportKind::Serial ? "serial" : "ble"},
      {"ble_adapter", r.ble_adapter},
      {"ble_connect_timeout_s", number(c.ble_connect_timeout_s)},
      {"battery_low_v", number(c.battery_low_v)},
      {"battery_empty_v", number(c.battery_empty_v)},
      {"battery_samples", number(c.battery_samples)},
      {"model", r.model == Model::Unknown ? "auto" : "not auto"},
      {"max_units", number(cal.max_units)},
      {"track_m", number(cal.track_m)},
  };
  for (const auto& [k, value] : applied) {
    ASSERT_TRUE(documented.count(k)) << file << " states no default for " << k;
    // "serial = USB dongle", "auto: whatever ...", "3.6, the official ...": the value is the first word.
    const std::string stated = documented.at(k).substr(0, documented.at(k).find_first_of(k == "scan" ? "" : " :"));
    // Numbers as numbers: "3.0" states 3.
    char* end = nullptr;
    const double stated_number = std::strtod(stated.c_str(), &end);
    if (*end == '\0' && !stated.empty())
      EXPECT_EQ(stated_number, std::stod(value)) << file << ": the default of " << k << " is " << value;
    else EXPECT_EQ(stated, value) << file << ": the default of " << k;
  }
  // A default stated for a key this test does not know is checked nowhere: add it above.
  for (const auto& [k, text] : documented) EXPECT_TRUE(applied.count(k)) << k << " (default " << text << ")";
}

TEST(HamsterConfig, ErrorsNameFileLineAndColumn) {
  EXPECT_EQ(errorOf("robots:\n  - name: R1\n    address: 67E1A48B4BZZ\n    calibration: {mps_per_unit: 0.002}\n"),
            "h.yaml:3:14: robot R1: address '67E1A48B4BZZ' is neither 12 hex digits (wire order) nor "
            "AA:BB:CC:DD:EE:FF");
  EXPECT_NE(errorOf("robots:\n  - name: R1\n    address: 67E1A48B4BD9\n")
                .find("h.yaml:2:5: robot R1: missing key 'calibration' (measure it with scripts/calibrate_hamster.py)"),
            std::string::npos);
  EXPECT_NE(errorOf("robots:\n  - name: R1\n    address: 67E1A48B4BD9\n    calibration: {mps_per_unit: -1}\n")
                .find("mps_per_unit must be > 0"),
            std::string::npos);
  EXPECT_NE(
      errorOf(std::string(kRobot) + "  - name: R2\n    address: 67e1a48b4bd9\n    calibration: {mps_per_unit: 1}\n")
          .find("h.yaml:6:14: address D9:4B:8B:A4:E1:67 of robot R2 is also used by robots[0]"),
      std::string::npos);
  EXPECT_NE(errorOf(std::string("speed: 3\n") + kRobot).find("h.yaml:1:1: unknown key 'speed'"), std::string::npos);
  EXPECT_NE(errorOf("robots:\n  - name: R1\n    address: 67E1A48B4BD9\n    model: turtle\n"
                    "    calibration: {mps_per_unit: 0.002}\n")
                .find("model 'turtle'"),
            std::string::npos);
  EXPECT_NE(errorOf("robots: [").find("YAML syntax error"), std::string::npos);
  EXPECT_NE(errorOf("port_dir: /dev\n").find("missing key 'robots'"), std::string::npos);
  // A fraction is not silently truncated.
  EXPECT_NE(errorOf(std::string("identify_retries: 2.5\n") + kRobot)
                .find("h.yaml:1:19: identify_retries must be an integer in 1..1000 (got 2.5)"),
            std::string::npos)
      << errorOf(std::string("identify_retries: 2.5\n") + kRobot);
  EXPECT_EQ(parseBridgeConfig(std::string("identify_retries: 3\n") + kRobot, "h.yaml").identify_retries, 3);
  EXPECT_NE(errorOf(std::string("search_quiet_s: -1\n") + kRobot).find("h.yaml:1:17: search_quiet_s must be in 0..600"),
            std::string::npos)
      << errorOf(std::string("search_quiet_s: -1\n") + kRobot);
  EXPECT_EQ(parseBridgeConfig(std::string("search_quiet_s: 0\n") + kRobot, "h.yaml").search_quiet_s, 0.0);
  // An invalid address is reported once, not also as a duplicate of another invalid one.
  const std::string bad = errorOf(
      "robots:\n  - name: R1\n    address: nonsense\n    calibration: {mps_per_unit: 0.002}\n"
      "  - name: R2\n    address: rubbish\n    calibration: {mps_per_unit: 0.002}\n");
  EXPECT_NE(bad.find("address 'nonsense'"), std::string::npos) << bad;
  EXPECT_NE(bad.find("address 'rubbish'"), std::string::npos) << bad;
  EXPECT_EQ(bad.find("also used by"), std::string::npos) << bad;
  EXPECT_NE(errorOf(std::string("battery_low_v: 3.4\nbattery_empty_v: 3.5\n") + kRobot)
                .find("battery_empty_v (3.500000) must be below battery_low_v (3.400000)"),
            std::string::npos);
  const BridgeConfig c =
      parseBridgeConfig(std::string("battery_low_v: 3.7\ncommand_max_age_s: 0.1\n") + kRobot, "h.yaml");
  EXPECT_DOUBLE_EQ(c.battery_low_v, 3.7);
  EXPECT_DOUBLE_EQ(c.battery_empty_v, 3.0);
  EXPECT_DOUBLE_EQ(c.command_max_age_s, 0.1);
}

TEST(HamsterConfig, WheelUnitsFollowTheCalibration) {
  Calibration c;
  c.left_mps_per_unit = 0.002;
  c.right_mps_per_unit = 0.0025;
  WheelUnits u = wheelUnitsFromSpeeds(c, 0.06, 0.06);
  EXPECT_EQ(u.left, 30);
  EXPECT_EQ(u.right, 24);
  EXPECT_FALSE(u.saturated);
  u = wheelUnitsFromSpeeds(c, -0.0609, 0.0);
  EXPECT_EQ(u.left, -30);  // rounds to nearest
  EXPECT_EQ(u.right, 0);
}

TEST(HamsterConfig, SaturationKeepsTheCurvature) {
  Calibration c;
  c.left_mps_per_unit = c.right_mps_per_unit = 0.001;
  c.max_units = 80;
  const WheelUnits u = wheelUnitsFromSpeeds(c, 0.2, 0.1);  // 200 / 100 units wanted
  EXPECT_TRUE(u.saturated);
  EXPECT_EQ(u.left, 80);
  EXPECT_EQ(u.right, 40);
}

TEST(HamsterConfig, NonFiniteCommandsAreRefused) {
  Calibration c;
  c.left_mps_per_unit = c.right_mps_per_unit = 0.001;
  EXPECT_THROW(wheelUnitsFromSpeeds(c, std::nan(""), 0.0), ddace::Error);
  EXPECT_THROW(wheelUnitsFromSpeeds(c, 0.0, INFINITY), ddace::Error);
  EXPECT_THROW(wheelUnitsFromSpeeds(Calibration{}, 0.1, 0.1), ddace::Error);  // no calibration
}

TEST(HamsterConfig, TwistToWheelSpeeds) {
  double l = 0, r = 0;
  wheelSpeedsFromTwist(0.1, 2.0, 0.04, &l, &r);  // turning left: right wheel faster
  EXPECT_NEAR(l, 0.06, 1e-12);
  EXPECT_NEAR(r, 0.14, 1e-12);
}

TEST(HamsterConfig, TransportKeys) {
  const std::string cal = "    calibration: {mps_per_unit: 0.002}\n";
  // Serial is the default; a global transport applies to robots without their own.
  BridgeConfig c = parseBridgeConfig(kRobot, "h.yaml");
  EXPECT_EQ(c.robots[0].transport, TransportKind::Serial);
  EXPECT_NE(
      errorOf("transport: usb\n" + std::string(kRobot)).find("h.yaml:1:12: transport 'usb' is not one of serial, ble"),
      std::string::npos);
  EXPECT_NE(errorOf("robots:\n  - name: R1\n    address: 67E1A48B4BD9\n    ble_adapter: hci1\n" + cal)
                .find("h.yaml:4:18: robot R1: ble_adapter applies to transport ble only"),
            std::string::npos);
  const std::string ble_robot = "robots:\n  - name: R1\n    address: 67E1A48B4BD9\n    transport: ble\n";
  if (!bleBuilt()) {
    // Never silently serial: a clear error naming the place and the build option.
    EXPECT_NE(errorOf(ble_robot + cal)
                  .find("h.yaml:4:16: robot R1 transport 'ble': this ddace was built without "
                        "direct BLE (CMake option DDACE_WITH_BLE=OFF"),
              std::string::npos);
    EXPECT_NE(errorOf("transport: ble\n" + std::string(kRobot)).find("h.yaml:1:12: transport 'ble': this ddace"),
              std::string::npos);
    return;
  }
  c = parseBridgeConfig("transport: ble\nble_adapter: hci1\nble_connect_timeout_s: 5\n" + std::string(kRobot) +
                            "  - name: R2\n    address: 67E1A48B4BDA\n    transport: serial\n" + cal,
                        "h.yaml");
  EXPECT_EQ(c.robots[0].transport, TransportKind::Ble);
  EXPECT_EQ(c.robots[0].ble_adapter, "hci1");
  EXPECT_EQ(c.robots[0].model, Model::Hamster);  // auto means the original Hamster over BLE
  EXPECT_EQ(c.robots[1].transport, TransportKind::Serial);
  EXPECT_DOUBLE_EQ(c.ble_connect_timeout_s, 5.0);
  EXPECT_NE(errorOf(ble_robot + "    model: hamster_s\n" + cal)
                .find("h.yaml:5:12: robot R1: transport ble drives the original Hamster only"),
            std::string::npos);
  EXPECT_NE(errorOf(ble_robot + "    port_hints: [ttyUSB0]\n" + cal)
                .find("h.yaml:5:17: robot R1: port_hints apply to transport serial only"),
            std::string::npos);
  EXPECT_NE(errorOf(ble_robot + "    ble_adapter: /org/bluez\n" + cal)
                .find("h.yaml:5:18: robot R1 ble_adapter "
                      "'/org/bluez' is not a BlueZ adapter name"),
            std::string::npos);
}

TEST(HamsterConfig, SelectRobotsKeepsTheConfigOrderAndRefusesUnknownNames) {
  const BridgeConfig c = parseBridgeConfig(
      "robots:\n"
      "  - {name: R1, address: '000000000001', calibration: {mps_per_unit: 0.002}}\n"
      "  - {name: R2, address: '000000000002', calibration: {mps_per_unit: 0.002}}\n"
      "  - {name: R3, address: '000000000003', calibration: {mps_per_unit: 0.002}}\n",
      "h.yaml");
  auto names = [](const std::vector<RobotConfig>& robots) {
    std::vector<std::string> out;
    for (const auto& r : robots) out.push_back(r.name);
    return out;
  };
  EXPECT_EQ(names(selectRobots(c, {}, "parameter ~robots", "h.yaml")), (std::vector<std::string>{"R1", "R2", "R3"}));
  EXPECT_EQ(names(selectRobots(c, {"R3", "R1"}, "parameter ~robots", "h.yaml")),
            (std::vector<std::string>{"R1", "R3"}));
  try {
    selectRobots(c, {"R2", "R9"}, "parameter /bridge/robots", "h.yaml");
    FAIL() << "an unknown robot name was accepted";
  } catch (const ddace::Error& e) {
    EXPECT_STREQ(e.what(), "parameter /bridge/robots: robot 'R9' is not in h.yaml");
  }
}

TEST(HamsterConfig, ABridgeGivenATaskNamesTheConfiguredRobotsTheTaskDoesNotHave) {
  // The shipped file configures R1..R4; a task of two robots connects those two and says
  // which others it leaves out (and that nothing needs doing), so a config of another task
  // never goes unnoticed.
  const BridgeConfig c = parseBridgeConfig(
      "robots:\n"
      "  - {name: R1, address: '000000000001', calibration: {mps_per_unit: 0.002}}\n"
      "  - {name: R2, address: '000000000002', calibration: {mps_per_unit: 0.002}}\n"
      "  - {name: R3, address: '000000000003', calibration: {mps_per_unit: 0.002}}\n"
      "  - {name: R4, address: '000000000004', calibration: {mps_per_unit: 0.002}}\n",
      "h.yaml");
  EXPECT_EQ(unusedRobotsWarning(c, {"R2", "R1"}, "fetch2", "h.yaml"),
            "h.yaml also configures R3, R4, which task 'fetch2' does not have: not connected (no action needed; "
            "remove them from the file to silence this)");
  EXPECT_EQ(unusedRobotsWarning(c, {"R1", "R2", "R3", "R4"}, "task4", "h.yaml"), "");
  EXPECT_EQ(selectRobots(c, {"R2", "R1"}, "task /t (parameter ~task)", "h.yaml").size(), 2u);
  // A robot of the task the config lacks is an error naming the task, not a robot left out.
  try {
    selectRobots(c, {"R1", "R5"}, "task /t (parameter ~task)", "h.yaml");
    FAIL() << "a robot of the task missing from the config was accepted";
  } catch (const ddace::Error& e) {
    EXPECT_STREQ(e.what(), "task /t (parameter ~task): robot 'R5' is not in h.yaml");
  }
}

TEST(HamsterConfig, MockRobotsStandInForTheConfiguredOnesInARow) {
  const BridgeConfig c = parseBridgeConfig(
      "robots:\n"
      "  - {name: R1, address: '000000000001', calibration: {left_mps_per_unit: 0.002, right_mps_per_unit: 0.0021}}\n"
      "  - {name: R2, address: '000000000002', model: hamster_s, calibration: {mps_per_unit: 0.0019, track_m: 0.04}}\n",
      "h.yaml");
  const MockRobotSettings a = mockSettingsFor(c.robots[0], 0, "/tmp/links", std::nullopt, 0.5);
  EXPECT_EQ(a.name, "R1");
  EXPECT_EQ(a.address.wire(), "000000000001");
  EXPECT_EQ(a.model, Model::Hamster);  // auto-detected in the config: the mock is a Hamster
  EXPECT_EQ(a.link_path, "/tmp/links/hamster_R1");
  EXPECT_DOUBLE_EQ(a.left_mps_per_unit, 0.002);  // perfectly calibrated
  EXPECT_DOUBLE_EQ(a.right_mps_per_unit, 0.0021);
  EXPECT_DOUBLE_EQ(a.robot_timeout_s, 0.5);
  const MockRobotSettings b = mockSettingsFor(c.robots[1], 1, "/tmp/links", 0.0025, 0.0);
  EXPECT_EQ(b.model, Model::HamsterS);
  EXPECT_DOUBLE_EQ(b.left_mps_per_unit, 0.0025);  // the truth a calibration has to find
  EXPECT_DOUBLE_EQ(b.right_mps_per_unit, 0.0025);
  EXPECT_DOUBLE_EQ(b.track_m, 0.04);
  EXPECT_GT(std::hypot(b.x_m - a.x_m, b.y_m - a.y_m), 0.1);  // side by side, not on top of each other
  EXPECT_NE(a.seed, b.seed);
  EXPECT_THROW(mockSettingsFor(c.robots[0], 0, "/tmp/links", 0.0, 0.0), ddace::Error);
}
