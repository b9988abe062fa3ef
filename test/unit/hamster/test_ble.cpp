// The direct-BLE transport against a mock BlueZ (mock_bluez.py) on a private
// dbus-daemon: connection through discovery, FF identification, sensor
// notifications decoded through RobotLink, wheel commands written as 20-byte
// payloads, malformed notifications, disconnect → reconnect with zero wheels.
// No real adapter or robot is involved. Only in builds with DDACE_WITH_BLE.
#include <gtest/gtest.h>

#include "ddace/common/error.h"
#include "ddace/hamster/config.h"

#if DDACE_WITH_BLE

#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <systemd/sd-bus.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <thread>
#include <tuple>

#include "ddace/common/clock.h"
#include "ddace/common/repository.h"
#include "ddace/hamster/ble_transport.h"
#include "ddace/hamster/link.h"

extern char** environ;

using namespace ddace::hamster;
using ddace::monotonicS;

namespace {

const char* kDisplayAddress = "D9:4B:8B:A4:E1:67";

/// Starts `argv` with its stdout on a pipe; returns the pid (-1 on failure).
pid_t spawnWithStdout(const std::vector<std::string>& argv, int* stdout_fd) {
  int fds[2];
  if (::pipe(fds) != 0) return -1;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int r = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  if (r != 0) {
    ::close(fds[0]);
    return -1;
  }
  *stdout_fd = fds[0];
  return pid;
}

/// One line from fd (without the newline); empty on timeout or end of file.
std::string readLine(int fd, double timeout_s) {
  std::string line;
  const double end = monotonicS() + timeout_s;
  while (monotonicS() < end) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    char c = 0;
    if (::read(fd, &c, 1) != 1) break;
    if (c == '\n') return line;
    line += c;
  }
  return std::string();
}

void stop(pid_t& pid) {
  if (pid <= 0) return;
  ::kill(pid, SIGTERM);
  ::waitpid(pid, nullptr, 0);
  pid = -1;
}

/// A private bus with the mock BlueZ on it; DBUS_SYSTEM_BUS_ADDRESS points there
/// while the fixture lives.
class BleTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* dbus_daemon = "/usr/bin/dbus-daemon";
    ASSERT_EQ(::access(dbus_daemon, X_OK), 0)
        << dbus_daemon << " is missing: the BLE test needs it (Debian package dbus-daemon; scripts/setup installs it)";
    int out = -1;
    daemon_ = spawnWithStdout({dbus_daemon, "--session", "--nofork", "--nopidfile", "--print-address=1"}, &out);
    ASSERT_GT(daemon_, 0) << "cannot start " << dbus_daemon;
    address_ = readLine(out, 10.0);
    ::close(out);
    ASSERT_FALSE(address_.empty()) << "dbus-daemon printed no bus address within 10 s";
    if (const char* old = std::getenv("DBUS_SYSTEM_BUS_ADDRESS")) old_address_ = old;
    ::setenv("DBUS_SYSTEM_BUS_ADDRESS", address_.c_str(), 1);

    const std::string script =
        (ddace::findRepository("", {"test/unit/hamster/mock_bluez.py"}) / "test/unit/hamster/mock_bluez.py").string();
    mock_ = spawnWithStdout({"/usr/bin/python3", script, "--address", kDisplayAddress, "--connect-delay", "0.3"},
                            &mock_out_);
    ASSERT_GT(mock_, 0) << "cannot start /usr/bin/python3 " << script;
    ASSERT_EQ(readLine(mock_out_, 20.0), "ready")
        << "the mock BlueZ did not come up (its error is above; it needs python3-dbus and python3-gi, "
           "which scripts/setup installs)";

    ASSERT_GE(sd_bus_new(&control_), 0);
    ASSERT_GE(sd_bus_set_address(control_, address_.c_str()), 0);
    ASSERT_GE(sd_bus_set_bus_client(control_, 1), 0);
    ASSERT_GE(sd_bus_start(control_), 0) << "cannot connect to the private bus " << address_;
  }

  void TearDown() override {
    if (control_) control_ = sd_bus_flush_close_unref(control_);
    stop(mock_);
    if (mock_out_ >= 0) ::close(mock_out_);
    stop(daemon_);
    if (old_address_.empty()) {
      ::unsetenv("DBUS_SYSTEM_BUS_ADDRESS");
    } else {
      ::setenv("DBUS_SYSTEM_BUS_ADDRESS", old_address_.c_str(), 1);
    }
  }

  // ---- the mock's control interface
  void control(const char* member, const std::vector<uint8_t>* bytes = nullptr, int flag = -1) {
    sd_bus_message* m = nullptr;
    sd_bus_message* reply = nullptr;
    sd_bus_error e = SD_BUS_ERROR_NULL;
    ASSERT_GE(
        sd_bus_message_new_method_call(control_, &m, "org.bluez", "/org/ddace/mock", "org.ddace.MockBluez", member), 0);
    if (bytes) {
      ASSERT_GE(sd_bus_message_append_array(m, 'y', bytes->data(), bytes->size()), 0);
    }
    if (flag >= 0) {
      ASSERT_GE(sd_bus_message_append(m, "b", flag), 0);
    }
    const int r = sd_bus_call(control_, m, 0, &e, &reply);
    EXPECT_GE(r, 0) << "mock " << member << ": " << (e.message ? e.message : std::strerror(-r));
    sd_bus_error_free(&e);
    sd_bus_message_unref(reply);
    sd_bus_message_unref(m);
  }
  void setSensor(const Payload& p) {
    std::vector<uint8_t> v(p.begin(), p.end());
    control("SetSensor", &v);
  }
  void notifyRaw(const std::vector<uint8_t>& v) { control("Notify", &v); }

  /// (connection number, payload, options["type"]) of every WriteValue.
  std::vector<std::tuple<uint32_t, std::vector<uint8_t>, std::string>> writes() {
    std::vector<std::tuple<uint32_t, std::vector<uint8_t>, std::string>> out;
    sd_bus_message* reply = nullptr;
    sd_bus_error e = SD_BUS_ERROR_NULL;
    if (sd_bus_call_method(control_, "org.bluez", "/org/ddace/mock", "org.ddace.MockBluez", "Writes", &e, &reply, "") <
        0) {
      ADD_FAILURE() << "mock Writes: " << (e.message ? e.message : "?");
      sd_bus_error_free(&e);
      return out;
    }
    sd_bus_message_enter_container(reply, 'a', "(uays)");
    while (sd_bus_message_enter_container(reply, 'r', "uays") > 0) {
      uint32_t connection = 0;
      const void* data = nullptr;
      size_t size = 0;
      const char* type = nullptr;
      sd_bus_message_read(reply, "u", &connection);
      sd_bus_message_read_array(reply, 'y', &data, &size);
      sd_bus_message_read(reply, "s", &type);
      sd_bus_message_exit_container(reply);
      const auto* bytes = static_cast<const uint8_t*>(data);
      out.emplace_back(connection, std::vector<uint8_t>(bytes, bytes + size), type);
    }
    sd_bus_message_unref(reply);
    return out;
  }

  std::vector<std::string> calls() {
    std::vector<std::string> out;
    sd_bus_message* reply = nullptr;
    if (sd_bus_call_method(control_, "org.bluez", "/org/ddace/mock", "org.ddace.MockBluez", "Calls", nullptr, &reply,
                           "") < 0) {
      ADD_FAILURE() << "mock Calls failed";
      return out;
    }
    char** strv = nullptr;
    sd_bus_message_read_strv(reply, &strv);
    for (char** s = strv; s && *s; ++s) {
      out.emplace_back(*s);
      std::free(*s);
    }
    std::free(strv);
    sd_bus_message_unref(reply);
    return out;
  }

  static bool runUntil(const std::function<bool()>& step, double timeout_s) {
    const double end = monotonicS() + timeout_s;
    while (monotonicS() < end) {
      if (step()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }

  Address address() const { return *Address::parse(kDisplayAddress); }

  std::string address_, old_address_;
  pid_t daemon_ = -1, mock_ = -1;
  int mock_out_ = -1;
  sd_bus* control_ = nullptr;
};

Payload sensorPayload() {
  Sensors s;
  s.model = Model::Hamster;
  s.proximity_left = 17;
  s.proximity_right = 42;
  s.floor_left = 80;
  s.floor_right = 91;
  s.accel_x = 100;
  s.accel_y = -200;
  s.accel_z = 16000;
  s.rssi_dbm = -61;
  s.has_light = true;
  s.light = 345;
  return encodeSensors(Model::Hamster, s, true);
}

size_t countOf(const std::vector<std::string>& v, const std::string& s) {
  return static_cast<size_t>(std::count(v.begin(), v.end(), s));
}

TEST_F(BleTest, TransportConnectsIdentifiesAndPresentsTheDongleProtocol) {
  BleTransport t(bleEndpoint("hci0", address()), 10.0);
  EXPECT_EQ(t.name(), "ble:hci0/D9:4B:8B:A4:E1:67");
  EXPECT_EQ(t.devicePath(), "/org/bluez/hci0/dev_D9_4B_8B_A4_E1_67");
  t.open();
  EXPECT_TRUE(t.isOpen());
  EXPECT_GE(t.fd(), 0);
  EXPECT_TRUE(t.connecting());
  char buf[512];
  // The mock does not know the robot until discovery ran, and connects after 0.3 s.
  ASSERT_TRUE(runUntil([&] { return t.read(buf, sizeof buf) == 0 && !t.connecting(); }, 10.0)) << "no connection";
  const auto c = calls();
  ASSERT_GE(c.size(), 3u);
  const auto at = [&](const std::string& s) { return std::find(c.begin(), c.end(), s) - c.begin(); };
  EXPECT_LT(at("StartDiscovery"), at("Connect"));
  EXPECT_LT(at("Connect"), at("StartNotify"));
  EXPECT_EQ(countOf(c, "StartNotify"), 1u);

  // FF is answered locally, in the dongle's format.
  t.flush();
  t.write("FF\r", 3);
  std::string text;
  LineAssembler lines;
  std::vector<ParsedLine> parsed;
  auto collect = [&] {
    const size_t n = t.read(buf, sizeof buf);
    lines.push(buf, n, [&](std::string_view l) { parsed.push_back(parseLine(l)); });
    return n;
  };
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        return std::any_of(parsed.begin(), parsed.end(),
                           [](const ParsedLine& p) { return p.kind == LineKind::Identify; });
      },
      2.0));
  const auto id =
      std::find_if(parsed.begin(), parsed.end(), [](const ParsedLine& p) { return p.kind == LineKind::Identify; });
  EXPECT_EQ(id->identify.model, Model::Hamster);
  EXPECT_EQ(id->identify.name, "Hamster");
  EXPECT_EQ(id->identify.address, address());
  EXPECT_EQ(id->identify.address.wire(), "67E1A48B4BD9");

  // Notifications become 54-character sensor lines with our address.
  setSensor(sensorPayload());
  parsed.clear();
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        return std::any_of(parsed.begin(), parsed.end(), [&](const ParsedLine& p) {
          return p.kind == LineKind::Data && p.payload == sensorPayload();
        });
      },
      2.0));
  for (const auto& p : parsed) {
    if (p.kind == LineKind::Data) {
      EXPECT_EQ(p.address, address());
    }
  }

  // A notification of the wrong length: counted, and a line RobotLink drops.
  notifyRaw(std::vector<uint8_t>(19, 0x11));
  parsed.clear();
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        return std::any_of(parsed.begin(), parsed.end(),
                           [](const ParsedLine& p) { return p.kind == LineKind::Malformed; });
      },
      2.0));
  EXPECT_EQ(t.malformedNotifications(), 1u);

  // A motoring line goes out as its 20-byte payload, written without response.
  Effector e;
  e.left_wheel = 20;
  e.right_wheel = -10;
  const Payload motoring = encodeEffector(Model::Hamster, e);
  const std::string line = encodeLine(motoring, address());
  t.write(line.data(), 20);  // in two pieces, as a byte stream may come
  t.write(line.data() + 20, line.size() - 20);
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        const auto w = writes();
        return !w.empty() && std::get<1>(w.back()) == std::vector<uint8_t>(motoring.begin(), motoring.end());
      },
      2.0));
  EXPECT_EQ(std::get<2>(writes().back()), "command");

  // A congested link: motion commands beyond kMaxPendingWrites unacknowledged writes are
  // refused (never queued), a stop still goes out.
  control("HoldWrites", nullptr, 1);
  Effector slow;
  slow.left_wheel = 5;
  slow.right_wheel = 5;
  const std::string slow_line = encodeLine(encodeEffector(Model::Hamster, slow), address());
  const size_t before = writes().size();
  // Nothing is read meanwhile, so no acknowledgement is processed: the count only grows
  // (it may start above 0 with an earlier write not yet acknowledged).
  size_t accepted = 0;
  bool refused = false;
  for (int i = 0; i <= BleTransport::kMaxPendingWrites && !refused; ++i) {
    try {
      t.write(slow_line.data(), slow_line.size());
      ++accepted;
    } catch (const ddace::Error& err) {
      refused = true;
      EXPECT_NE(std::string(err.what()).find("not acknowledged"), std::string::npos) << err.what();
    }
  }
  ASSERT_TRUE(refused) << "more than kMaxPendingWrites unacknowledged writes accepted";
  EXPECT_GE(accepted, 1u);
  ASSERT_TRUE(runUntil([&] { return writes().size() == before + accepted; }, 2.0));
  const Payload stop = encodeEffector(Model::Hamster, Effector{});
  const std::string stop_line = encodeLine(stop, address());
  EXPECT_NO_THROW(t.write(stop_line.data(), stop_line.size()));
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        const auto w = writes();
        return !w.empty() && std::get<1>(w.back()) == std::vector<uint8_t>(stop.begin(), stop.end());
      },
      2.0));
  EXPECT_EQ(writes().size(), before + accepted + 1) << "the refused command went out";
  control("HoldWrites", nullptr, 0);
  ASSERT_TRUE(runUntil(
      [&] {
        collect();
        try {
          t.write(slow_line.data(), slow_line.size());  // accepted again once acknowledged
          return true;
        } catch (const ddace::Error&) {
          return false;
        }
      },
      2.0));

  // Anything else written is refused, as is a line for another robot.
  EXPECT_THROW(t.write("hello\r", 6), ddace::Error);
  const std::string foreign = encodeLine(motoring, *Address::parse("D9:4B:8B:A4:E1:68"));
  EXPECT_THROW(t.write(foreign.data(), foreign.size()), ddace::Error);

  // The device object vanishing is a lost link.
  control("Vanish");
  try {
    runUntil([&] { return collect() == 12345; }, 2.0);
    ADD_FAILURE() << "read() did not throw after the device vanished";
  } catch (const ddace::Error& err) {
    EXPECT_NE(std::string(err.what()).find("vanished"), std::string::npos) << err.what();
  }
  t.close();
  EXPECT_FALSE(t.isOpen());
  EXPECT_EQ(t.fd(), -1);
}

TEST_F(BleTest, RobotLinkDrivesReconnectsAndFailsSafe) {
  BridgeConfig bridge;
  bridge.command_timeout_s = 0.2;
  bridge.link_timeout_s = 1.0;  // generous: the machine running the test may be busy
  bridge.ble_connect_timeout_s = 10.0;
  RobotConfig r;
  r.name = "R1";
  r.address = address();
  r.model = Model::Hamster;
  r.transport = TransportKind::Ble;
  r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.0015;
  RobotLink link(r, bridge, std::make_shared<PortDirectory>(), transportFactoryFor(r, bridge));
  setSensor(sensorPayload());

  std::vector<CycleReport> reports, all;
  bool command = false;
  auto step = [&] {
    const double t = monotonicS();
    if (command) link.setWheelCommand(0.03, -0.015, t);  // 20 and -10 units
    reports.clear();
    link.poll(t, reports);
    all.insert(all.end(), reports.begin(), reports.end());
  };
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return link.state() == LinkState::Streaming;
      },
      10.0))
      << "not streaming: " << link.stats().last_error;
  EXPECT_EQ(link.port(), "ble:hci0/D9:4B:8B:A4:E1:67");
  EXPECT_EQ(link.model(), Model::Hamster);
  EXPECT_EQ(link.stats().connects, 1u);

  // Sensor notifications decoded through RobotLink.
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return all.size() >= 5;
      },
      3.0));
  const Sensors& s = all.back().sensors;
  EXPECT_EQ(s.proximity_left, 17);
  EXPECT_EQ(s.proximity_right, 42);
  EXPECT_EQ(s.floor_left, 80);
  EXPECT_EQ(s.floor_right, 91);
  EXPECT_EQ(s.accel_x, 100);
  EXPECT_EQ(s.accel_y, -200);
  EXPECT_EQ(s.accel_z, 16000);
  EXPECT_EQ(s.rssi_dbm, -61);
  ASSERT_TRUE(s.has_light);
  EXPECT_EQ(s.light, 345);
  // No command yet: every answer has zero wheels.
  for (const auto& [connection, bytes, type] : writes()) {
    ASSERT_EQ(bytes.size(), kPayloadBytes);
    EXPECT_EQ(bytes[3], 0);
    EXPECT_EQ(bytes[4], 0);
  }

  // Wheel commands arrive as the 20-byte motoring payload, one per sensor line.
  Effector e;
  e.left_wheel = 20;
  e.right_wheel = -10;
  const Payload driving = encodeEffector(Model::Hamster, e);
  const std::vector<uint8_t> driving_bytes(driving.begin(), driving.end());
  command = true;
  const size_t before = writes().size();
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        const auto w = writes();
        return w.size() > before + 5 && std::get<1>(w.back()) == driving_bytes;
      },
      3.0));
  for (const auto& [connection, bytes, type] : writes()) {
    EXPECT_EQ(connection, 1u);
    EXPECT_EQ(type, "command");
  }
  EXPECT_GE(link.stats().lines_sent, link.stats().lines_ok - 1);

  // A notification of the wrong length is counted and dropped; the link stays.
  const uint64_t dropped = link.stats().lines_dropped;
  notifyRaw(std::vector<uint8_t>(19, 0x11));
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return link.stats().lines_dropped > dropped;
      },
      2.0));
  EXPECT_EQ(link.stats().lines_dropped, dropped + 1);
  EXPECT_NE(link.stats().last_drop_reason.find("characters"), std::string::npos) << link.stats().last_drop_reason;
  EXPECT_EQ(link.state(), LinkState::Streaming);

  // The radio link breaks (Connected=false): link lost at once, reconnection.
  command = false;
  control("Drop");
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return link.stats().link_losses == 1;
      },
      2.0));
  EXPECT_NE(link.stats().last_error.find("Connected=false"), std::string::npos) << link.stats().last_error;
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return link.state() == LinkState::Streaming;
      },
      10.0))
      << "no reconnection: " << link.stats().last_error;
  EXPECT_EQ(link.stats().connects, 2u);
  EXPECT_EQ(countOf(calls(), "Connect"), 2u);
  // The last command is older than command_timeout_s: zero wheels until a fresh one.
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        size_t n = 0;
        for (const auto& w : writes()) n += std::get<0>(w) == 2;
        return n >= 5;
      },
      3.0));
  for (const auto& [connection, bytes, type] : writes()) {
    if (connection != 2) continue;
    EXPECT_EQ(bytes[3], 0);
    EXPECT_EQ(bytes[4], 0);
  }
  command = true;
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        const auto w = writes();
        return std::get<0>(w.back()) == 2 && std::get<1>(w.back()) == driving_bytes;
      },
      3.0));

  // Notifications stop while connected (stall): after link_timeout_s the link is lost
  // and the last line written is zero wheels, before the robot is disconnected.
  control("Stall", nullptr, 1);
  ASSERT_TRUE(runUntil(
      [&] {
        step();
        return link.stats().link_losses == 2;
      },
      3.0));
  const auto w = writes();
  ASSERT_FALSE(w.empty());
  EXPECT_EQ(std::get<1>(w.back())[3], 0);
  EXPECT_EQ(std::get<1>(w.back())[4], 0);
  ASSERT_TRUE(runUntil([&] { return countOf(calls(), "Disconnect") >= 1; }, 2.0));
}

}  // namespace

#endif  // DDACE_WITH_BLE

TEST(BleConfig, TransportKeyFollowsTheBuild) {
  const std::string yaml =
      "robots:\n"
      "  - name: R1\n"
      "    address: D9:4B:8B:A4:E1:67\n"
      "    transport: ble\n"
      "    calibration: {mps_per_unit: 0.0015}\n";
  if (ddace::hamster::bleBuilt()) {
    const auto cfg = ddace::hamster::parseBridgeConfig(yaml, "h.yaml");
    EXPECT_EQ(cfg.robots[0].transport, ddace::hamster::TransportKind::Ble);
    EXPECT_EQ(cfg.robots[0].ble_adapter, "hci0");
    EXPECT_EQ(cfg.robots[0].model, ddace::hamster::Model::Hamster);
  } else {
    try {
      ddace::hamster::parseBridgeConfig(yaml, "h.yaml");
      FAIL() << "transport ble accepted by a build without BLE";
    } catch (const ddace::Error& e) {
      EXPECT_NE(std::string(e.what()).find("h.yaml:4:16: robot R1 transport 'ble': this ddace was built without"),
                std::string::npos)
          << e.what();
    }
  }
}
