// The per-robot link against simulated dongles on pseudo-terminals: finding robots by
// address, the response-driven cycle, the command watchdog, link loss and recovery.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <thread>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/hamster/link.h"
#include "ddace/hamster/link_dir.h"
#include "ddace/hamster/mock_robot.h"
#include "ddace/hamster/scan.h"

using namespace ddace::hamster;
using ddace::monotonicS;

namespace {

class LinkTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/ddace_hamster_test_XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    links_.clear();
    mocks_.clear();
    std::filesystem::remove_all(dir_);
  }

  MockRobot& addMock(const std::string& name, const std::string& address, Model model, double mps_per_unit,
                     double robot_timeout_s = 0.0) {
    MockRobotSettings s;
    s.robot_timeout_s = robot_timeout_s;
    s.name = name;
    s.address = *Address::parse(address);
    s.model = model;
    s.link_path = dir_ + "/hamster_" + name;
    s.left_mps_per_unit = s.right_mps_per_unit = mps_per_unit;
    mocks_.push_back(std::make_unique<MockRobot>(s));
    return *mocks_.back();
  }

  RobotLink& addLink(const std::string& name, const std::string& address, Model model = Model::Unknown) {
    BridgeConfig bridge;
    bridge.port_dir = dir_;
    bridge.scan = {};
    RobotConfig r;
    r.name = name;
    r.address = *Address::parse(address);
    r.model = model;
    r.port_hints = {"hamster_*"};  // every link sees every port: it must pick by address
    r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.002;
    links_.push_back(std::make_unique<RobotLink>(r, bridge, ports_, serialTransportFactory()));
    return *links_.back();
  }

  /// Steps mocks and links every millisecond until `done()` or `timeout_s`.
  bool runUntil(const std::function<bool()>& done, double timeout_s) {
    const double end = monotonicS() + timeout_s;
    while (monotonicS() < end) {
      step();
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }
  void runFor(double seconds) {
    runUntil([] { return false; }, seconds);
  }
  void step() {
    const double t = monotonicS();
    for (auto& m : mocks_) m->step(t);
    for (auto& l : links_) {
      for (auto& cmd : commands_) {
        if (cmd.link == l.get()) l->setWheelCommand(cmd.left, cmd.right, t);
      }
      l->poll(t, reports_);
    }
  }

  struct Stream {
    RobotLink* link;
    double left, right;
  };
  std::vector<Stream> commands_;  // commands re-sent every step (like a 1 kHz publisher)
  std::string dir_;
  std::shared_ptr<PortDirectory> ports_ = std::make_shared<PortDirectory>();
  std::vector<std::unique_ptr<MockRobot>> mocks_;
  std::vector<std::unique_ptr<RobotLink>> links_;
  std::vector<CycleReport> reports_;
};

}  // namespace

TEST_F(LinkTest, FindsEachRobotByAddressAndDrivesItsWheels) {
  MockRobot& m1 = addMock("a", "000000000001", Model::Hamster, 0.002);
  MockRobot& m2 = addMock("b", "000000000002", Model::HamsterS, 0.002);
  MockRobot& m3 = addMock("c", "000000000003", Model::Hamster, 0.002);
  // Links created in the opposite order of the ports: the first port tried is wrong.
  RobotLink& l3 = addLink("R3", "000000000003");
  RobotLink& l2 = addLink("R2", "000000000002");
  RobotLink& l1 = addLink("R1", "000000000001");
  commands_ = {{&l1, 0.06, 0.06}, {&l2, -0.02, 0.04}, {&l3, 0.3, 0.15}};
  ASSERT_TRUE(runUntil(
      [&] {
        return m1.leftUnits() == 30 && m1.rightUnits() == 30 && m2.leftUnits() == -10 && m2.rightUnits() == 20 &&
               m3.leftUnits() == 100 && m3.rightUnits() == 50;
      },
      5.0))
      << "m1 " << int(m1.leftUnits()) << " m2 " << int(m2.leftUnits()) << " m3 " << int(m3.leftUnits());
  EXPECT_EQ(l1.state(), LinkState::Streaming);
  EXPECT_EQ(l2.model(), Model::HamsterS);
  EXPECT_EQ(l1.port(), dir_ + "/hamster_a");
  EXPECT_EQ(l2.port(), dir_ + "/hamster_b");
  EXPECT_EQ(l3.port(), dir_ + "/hamster_c");
  EXPECT_GT(l3.stats().saturated_cycles, 0u);
  // Response-driven: one motoring line per valid sensor line.
  runFor(0.3);
  EXPECT_EQ(m1.badLines(), 0u);
  EXPECT_EQ(l1.stats().lines_sent, l1.stats().lines_ok);
  EXPECT_NEAR(static_cast<double>(m1.motoringLines()), static_cast<double>(l1.stats().lines_sent), 2.0);
  EXPECT_EQ(l1.stats().lines_dropped, 0u);
  // Sensors arrive decoded, battery included.
  bool battery = false;
  for (const auto& r : reports_)
    battery = battery || (r.sensors.has_battery && std::abs(r.sensors.battery_v - 3.9) < 1e-9);
  EXPECT_TRUE(battery);
}

TEST_F(LinkTest, WatchdogZeroesWheelsWhenCommandsStop) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  commands_.clear();
  const double stop = monotonicS();
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 0 && m.rightUnits() == 0; }, 1.0));
  const double elapsed = monotonicS() - stop;
  EXPECT_GE(elapsed, 0.15);  // the command stays valid for command_timeout_s (0.2 s)
  EXPECT_LE(elapsed, 0.5);
  EXPECT_EQ(l.state(), LinkState::Streaming);
  EXPECT_GT(l.stats().stale_command_cycles, 0u);
}

// What the simulated table's bodies are driven by (sim_table_node): the units on the wire
// times the robot's true m/s per unit, and nothing once its firmware time-out passed
// without a motoring line, while the last units are still what the wire said.
TEST_F(LinkTest, MockWheelSpeedsAreTheUnitsOnTheWireUntilTheRobotTimesOut) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.003, 0.3);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, -0.05}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50 && m.rightUnits() == -25; }, 3.0));
  const auto [left, right] = m.wheelMps(monotonicS());
  EXPECT_DOUBLE_EQ(left, 50 * 0.003);  // the bridge's calibration (0.002) is not the robot's truth
  EXPECT_DOUBLE_EQ(right, -25 * 0.003);
  // The radio goes quiet (no link polls): the robot stops by itself after its time-out.
  const double quiet = monotonicS();
  while (monotonicS() < quiet + 0.2) m.step(monotonicS());
  EXPECT_GT(m.wheelMps(monotonicS()).first, 0.0);
  while (monotonicS() < quiet + 0.4) m.step(monotonicS());
  EXPECT_EQ(m.wheelMps(monotonicS()), std::make_pair(0.0, 0.0));
  EXPECT_EQ(m.leftUnits(), 50);
}

TEST_F(LinkTest, OneWayStallIsALinkLossThatStopsTheRobotAndRecovers) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  m.setFault(MockFault::Stall, 1.0, monotonicS());
  // No sensor line for 250 ms → the link sends a zero line (the robot still hears us) and reconnects.
  // The silence counts from the poll that received the last line, not from the fault: on a
  // loaded machine that poll can come well before it.
  ASSERT_TRUE(runUntil([&] { return l.state() != LinkState::Streaming; }, 1.0));
  ASSERT_FALSE(reports_.empty());
  EXPECT_GT(monotonicS() - reports_.back().time_s, 0.25);
  EXPECT_EQ(l.stats().link_losses, 1u);
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 0 && m.rightUnits() == 0; }, 0.1));
  // The dongle still answers FF, so the link re-identifies, but without sensor lines it
  // never drives; once the lines come back, driving resumes.
  runFor(0.4);
  EXPECT_EQ(m.leftUnits(), 0);
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming && m.leftUnits() == 50; }, 3.0));
  EXPECT_GE(l.stats().connects, 2u);
}

TEST_F(LinkTest, RadioDropRecoversWhenTheRobotComesBack) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  m.setFault(MockFault::Drop, 0.8, monotonicS());
  ASSERT_TRUE(runUntil([&] { return l.state() != LinkState::Streaming; }, 1.0));
  runFor(0.3);
  EXPECT_NE(l.state(), LinkState::Streaming);
  EXPECT_GT(l.stats().no_robot_lines, 0u);
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming && m.driven(monotonicS()); }, 4.0));
}

TEST_F(LinkTest, UnplugAndReplugReopensThroughTheSymlink) {
  MockRobot& m = addMock("a", "0000000000AA", Model::HamsterS, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  const std::string before = m.slavePath();
  m.setFault(MockFault::Unplug, 0.5, monotonicS());
  ASSERT_TRUE(runUntil([&] { return l.state() != LinkState::Streaming; }, 1.0));
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming && m.driven(monotonicS()); }, 4.0));
  EXPECT_EQ(l.stats().connects, 2u);
  EXPECT_EQ(m.leftUnits(), 50);
  (void)before;
}

TEST_F(LinkTest, GarbageIsCountedAndDroppedWhileDrivingContinues) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  const uint64_t ok_before = l.stats().lines_ok;
  m.setFault(MockFault::Garbage, 0.5, monotonicS());
  runFor(0.6);
  EXPECT_EQ(l.state(), LinkState::Streaming);
  EXPECT_EQ(l.stats().link_losses, 0u);
  EXPECT_GE(l.stats().lines_dropped, 20u);  // two bad lines per 20 ms cycle for 0.5 s
  EXPECT_GE(l.stats().lines_ok - ok_before, 20u);
  EXPECT_EQ(m.leftUnits(), 50);
}

TEST_F(LinkTest, NonFiniteCommandIsRefusedAndTheOldOneAgesOut) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  commands_.clear();
  EXPECT_THROW(l.setWheelCommand(std::nan(""), 0.1, monotonicS()), ddace::Error);
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 0; }, 1.0));
}

TEST_F(LinkTest, WrongModelInConfigIsRefused) {
  addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA", Model::HamsterS);
  runFor(0.5);
  EXPECT_NE(l.state(), LinkState::Streaming);
  EXPECT_NE(l.stats().last_error.find("config says hamster_s"), std::string::npos) << l.stats().last_error;
}

TEST_F(LinkTest, SurveyListsRobotsAndDonglesWithoutRobots) {
  addMock("a", "0000000000AA", Model::HamsterS, 0.002);
  MockRobot& lonely = addMock("b", "0000000000BB", Model::Hamster, 0.002);
  lonely.setFault(MockFault::Drop, 10.0, monotonicS());
  { std::ofstream(dir_ + "/hamster_plainfile") << "not a tty"; }
  std::atomic<bool> stop{false};
  std::thread robots([&] {
    while (!stop) {
      for (auto& m : mocks_) m->step(monotonicS());
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  });
  const auto survey = surveyPorts({"hamster_*"}, dir_, 0.5, serialTransportFactory());
  stop = true;
  robots.join();
  ASSERT_EQ(survey.size(), 3u);
  EXPECT_EQ(survey[0].port, dir_ + "/hamster_a");
  EXPECT_EQ(survey[0].status, PortSurvey::Status::Robot);
  EXPECT_TRUE(survey[0].identified);
  EXPECT_EQ(survey[0].identify.model, Model::HamsterS);
  EXPECT_EQ(survey[0].identify.address.wire(), "0000000000AA");
  EXPECT_EQ(survey[1].status, PortSurvey::Status::NoRobot);
  EXPECT_EQ(survey[2].status, PortSurvey::Status::OpenFailed);
  EXPECT_NE(survey[2].error.find("hamster_plainfile"), std::string::npos);
}

namespace {

/// A dongle in memory whose output can be blocked (as when CTS is never asserted).
struct MemoryDongle {
  std::string to_host, from_host;
  bool block_writes = false;
};

class MemoryTransport : public Transport {
 public:
  explicit MemoryTransport(std::shared_ptr<MemoryDongle> d) : d_(std::move(d)) {}
  void open() override { open_ = true; }
  void close() override { open_ = false; }
  bool isOpen() const override { return open_; }
  size_t read(char* buf, size_t size) override {
    const size_t n = std::min(size, d_->to_host.size());
    std::copy_n(d_->to_host.data(), n, buf);
    d_->to_host.erase(0, n);
    return n;
  }
  void write(const char* data, size_t size) override {
    if (d_->block_writes) throw ddace::Error("output queue full (flow control)");
    d_->from_host.append(data, size);
  }
  void flush() override {}
  std::string name() const override { return "memory"; }

 private:
  std::shared_ptr<MemoryDongle> d_;
  bool open_ = false;
};

}  // namespace

TEST(RobotLinkMemory, BlockedWritesCountAsALostLink) {
  auto dongle = std::make_shared<MemoryDongle>();
  BridgeConfig bridge;
  bridge.scan = {};
  RobotConfig r;
  r.name = "R1";
  r.address = *Address::parse("0000000000AA");
  r.port_hints = {"/proc/self/exe"};  // any existing path; the factory ignores it
  r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.002;
  RobotLink link(r, bridge, std::make_shared<PortDirectory>(),
                 [dongle](const std::string&) { return std::make_unique<MemoryTransport>(dongle); });
  std::vector<CycleReport> reports;
  double t = 0.0;
  link.poll(t, reports);
  ASSERT_EQ(link.state(), LinkState::Identifying);
  EXPECT_EQ(dongle->from_host, "FF\r");
  dongle->to_host = "FF,Hamster,04,01,0000000000AA\r";
  link.poll(t, reports);
  ASSERT_EQ(link.state(), LinkState::Identified);  // streaming only once the robot's lines come
  Sensors s;
  const std::string line = encodeLine(encodeSensors(Model::Hamster, s, true), r.address);
  link.setWheelCommand(0.1, 0.1, t);
  dongle->to_host = line;
  link.poll(t, reports);
  ASSERT_EQ(link.state(), LinkState::Streaming);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].left_sent, 50);
  dongle->block_writes = true;
  for (int i = 1; i <= 20; ++i) {  // lines keep coming every 20 ms, answers cannot leave
    t = 0.02 * i;
    link.setWheelCommand(0.1, 0.1, t);
    dongle->to_host += line;
    link.poll(t, reports);
    if (link.state() != LinkState::Streaming) break;
  }
  EXPECT_NE(link.state(), LinkState::Streaming);
  EXPECT_GE(t, 0.25);
  EXPECT_LE(t, 0.3);
  EXPECT_EQ(link.stats().link_losses, 1u);
  EXPECT_NE(link.stats().last_error.find("no motoring line could be written"), std::string::npos)
      << link.stats().last_error;
  EXPECT_GT(link.stats().write_failures, 10u);
}

TEST_F(LinkTest, DongleAnsweringFfWithoutItsRobotNeverStreamsNorFlaps) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  m.setFault(MockFault::Stall, 2.0, monotonicS());  // answers FF, no sensor line: the robot is gone
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Identified; }, 1.0)) << l.stats().last_error;
  runFor(1.5);
  EXPECT_EQ(l.state(), LinkState::Identified);
  EXPECT_EQ(l.stats().connects, 0u);
  EXPECT_EQ(l.stats().link_losses, 0u);
  EXPECT_EQ(m.identifyRequests(), 1u);  // the port was opened once and kept
  EXPECT_EQ(l.port(), dir_ + "/hamster_a");
  const LinkHealth h = l.health(monotonicS(), 0);
  EXPECT_EQ(h.level, LinkHealth::Level::Error);
  EXPECT_NE(h.summary.find("no sensor line"), std::string::npos) << h.summary;
  // The robot comes back: the first sensor line answered makes the link stream.
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming && m.leftUnits() == 50; }, 2.0));
  EXPECT_EQ(l.stats().connects, 1u);
  EXPECT_EQ(l.health(monotonicS(), 0).level, LinkHealth::Level::Ok);
}

TEST_F(LinkTest, LostLinkWaitsOnTheOpenPort) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  commands_ = {{&l, 0.1, 0.1}};
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 3.0));
  const uint64_t ff_before = m.identifyRequests();
  m.setFault(MockFault::Drop, 0.8, monotonicS());
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Lost; }, 1.0));
  EXPECT_EQ(l.port(), dir_ + "/hamster_a");
  EXPECT_EQ(l.health(monotonicS(), 1).level, LinkHealth::Level::Error);
  runFor(0.3);
  EXPECT_EQ(l.state(), LinkState::Lost);
  EXPECT_EQ(m.identifyRequests(), ff_before);  // not reopened, not re-identified
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming && m.leftUnits() == 50; }, 2.0));
  EXPECT_EQ(l.stats().link_losses, 1u);
  EXPECT_EQ(l.stats().connects, 2u);
  EXPECT_EQ(m.identifyRequests(), ff_before);
  // The loss shows in the next report even though the link is up again.
  EXPECT_EQ(l.health(monotonicS(), 1).level, LinkHealth::Level::Warn);
}

TEST_F(LinkTest, WarnsOnceAboutAForeignRobotAndListsThePortsSearched) {
  addMock("a", "0000000000F0", Model::Hamster, 0.002);  // nobody's robot
  addMock("b", "0000000000B2", Model::Hamster, 0.002);  // the other configured robot's
  BridgeConfig bridge;
  bridge.port_dir = dir_;
  bridge.scan = {};
  RobotConfig r1, r2;
  r1.name = "R1";
  r1.address = *Address::parse("0000000000B1");
  r2.name = "R2";
  r2.address = *Address::parse("0000000000B2");
  for (RobotConfig* r : {&r1, &r2}) {
    r->port_hints = {"hamster_*"};
    r->calibration.left_mps_per_unit = r->calibration.right_mps_per_unit = 0.002;
  }
  bridge.robots = {r1, r2};
  bridge.search_quiet_s = 0.0;  // warned from the first pass
  RobotLink l1(r1, bridge, ports_, serialTransportFactory());
  std::vector<std::string> warnings;
  const double end = monotonicS() + 1.5;  // three search passes
  while (monotonicS() < end) {
    for (auto& m : mocks_) m->step(monotonicS());
    l1.poll(monotonicS(), reports_);
    for (auto& w : l1.takeWarnings()) warnings.push_back(w);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_EQ(warnings.size(), 2u) << (warnings.empty() ? "" : warnings[0]);
  EXPECT_NE(warnings[0].find("carries robot F0:00:00:00:00:00, which is not in the config"), std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[1].find("robot B1:00:00:00:00:00 not found on 2 ports searched"), std::string::npos)
      << warnings[1];
  EXPECT_NE(warnings[1].find(dir_ + "/hamster_a (robot F0:00:00:00:00:00 answers there)"), std::string::npos)
      << warnings[1];
  EXPECT_NE(warnings[1].find(dir_ + "/hamster_b (robot B2:00:00:00:00:00 answers there)"), std::string::npos)
      << warnings[1];
  EXPECT_EQ(l1.health(monotonicS(), 0).level, LinkHealth::Level::Error);
}

TEST_F(LinkTest, MissingPortDirectoryIsReported) {
  BridgeConfig bridge;
  bridge.port_dir = dir_ + "/no_such_dir";
  bridge.scan = {"ttyUSB*"};
  RobotConfig r;
  r.name = "R1";
  r.address = *Address::parse("0000000000AA");
  r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.002;
  RobotLink l(r, bridge, ports_, serialTransportFactory());
  // Quiet while robots and links may still be coming up; in the diagnostics at once.
  for (double t = 0.0; t < bridge.search_quiet_s; t += bridge.rescan_interval_s) {
    l.poll(t, reports_);
    EXPECT_TRUE(l.takeWarnings().empty()) << "at " << t << " s";
  }
  EXPECT_NE(l.health(0.0, 0).summary.find("no_such_dir"), std::string::npos) << l.health(0.0, 0).summary;
  const double t0 = bridge.search_quiet_s + bridge.rescan_interval_s;
  l.poll(t0, reports_);
  const auto w = l.takeWarnings();
  ASSERT_FALSE(w.empty());
  EXPECT_NE(w[0].find("port directory " + dir_ + "/no_such_dir does not exist: set port_dir"), std::string::npos)
      << w[0];
  l.poll(t0 + 1.0, reports_);
  EXPECT_TRUE(l.takeWarnings().empty());  // not at every scan; it stays in the diagnostics
  l.poll(t0 + 1.0 + RobotLink::kWarningRepeatS, reports_);
  EXPECT_FALSE(l.takeWarnings().empty());  // but again after a while: a console scrolls
}

TEST_F(LinkTest, StaleOrFutureStampedCommandsAreRefusedAndCounted) {
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  RobotLink& l = addLink("R1", "0000000000AA");
  ASSERT_TRUE(runUntil([&] { return l.state() == LinkState::Streaming; }, 3.0));
  EXPECT_THROW(l.setWheelCommand(0.1, 0.1, monotonicS(), 0.25), ddace::Error);   // older than command_max_age_s
  EXPECT_THROW(l.setWheelCommand(0.1, 0.1, monotonicS(), -0.25), ddace::Error);  // from the future
  EXPECT_EQ(l.stats().refused_commands, 2u);
  runFor(0.1);
  EXPECT_EQ(m.leftUnits(), 0);
  l.setWheelCommand(0.1, 0.1, monotonicS(), 0.05);
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 50; }, 0.5));
  try {
    l.setWheelCommand(0.1, 0.1, monotonicS(), 1.5);
    FAIL();
  } catch (const ddace::Error& e) {
    EXPECT_NE(std::string(e.what()).find("1.500 s ago (more than command_max_age_s 0.200 s)"), std::string::npos)
        << e.what();
  }
}

TEST(RobotLinkMemory, BatteryHealthUsesTheConfiguredThresholdsOnTheMean) {
  auto dongle = std::make_shared<MemoryDongle>();
  BridgeConfig bridge;
  bridge.scan = {};
  bridge.battery_low_v = 3.7;
  bridge.battery_empty_v = 3.2;
  bridge.battery_samples = 4;
  RobotConfig r;
  r.name = "R1";
  r.address = *Address::parse("0000000000AA");
  r.port_hints = {"/proc/self/exe"};
  r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.002;
  RobotLink link(r, bridge, std::make_shared<PortDirectory>(),
                 [dongle](const std::string&) { return std::make_unique<MemoryTransport>(dongle); });
  std::vector<CycleReport> reports;
  link.poll(0.0, reports);
  dongle->to_host = "FF,Hamster,04,01,0000000000AA\r";
  link.poll(0.0, reports);
  EXPECT_EQ(link.state(), LinkState::Identified);
  EXPECT_EQ(link.health(0.0, 0).level, LinkHealth::Level::Error);
  double t = 0.0;
  auto feed = [&](double volts, int n) {
    for (int i = 0; i < n; ++i) {
      Sensors s;
      s.has_battery = true;
      s.battery_v = volts;
      t += 0.02;
      dongle->to_host += encodeLine(encodeSensors(Model::Hamster, s, false), r.address);
      link.poll(t, reports);
    }
  };
  feed(3.9, 4);
  ASSERT_EQ(link.state(), LinkState::Streaming);
  EXPECT_EQ(link.health(t, 0).level, LinkHealth::Level::Ok);
  feed(3.5, 1);  // one low reading: the mean of four (3.85 V) is fine
  EXPECT_EQ(link.health(t, 0).level, LinkHealth::Level::Ok);
  feed(3.5, 3);
  EXPECT_NEAR(link.batteryV(), 3.5, 1e-9);
  EXPECT_EQ(link.health(t, 0).level, LinkHealth::Level::Warn);
  EXPECT_NE(link.health(t, 0).summary.find("battery low (3.50 V < 3.70 V)"), std::string::npos);
  feed(3.1, 4);
  EXPECT_EQ(link.health(t, 0).level, LinkHealth::Level::Error);
}

namespace {

size_t fionread(int fd) {
  int n = 0;
  ::ioctl(fd, FIONREAD, &n);
  return static_cast<size_t>(n);
}

std::string drain(int fd) {
  std::string out;
  char buf[4096];
  for (int idle = 0; idle < 20;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n > 0) {
      out.append(buf, static_cast<size_t>(n));
      idle = 0;
    } else {
      ++idle;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  return out;
}

struct Pty {
  int master = -1, slave = -1;
  std::string path;
  Pty() {
    char name[128];
    if (::openpty(&master, &slave, name, nullptr, nullptr) != 0) throw ddace::Error("openpty failed");
    path = name;
    termios tio{};
    ::tcgetattr(master, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(master, TCSANOW, &tio);
    ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
  }
  ~Pty() {
    ::close(slave);
    ::close(master);
  }
};

}  // namespace

TEST(SerialTransportPty, PartialWriteIsDiscardedSoTheNextLineGoesOutWhole) {
  // How many bytes the far side's line discipline takes before the pty queues
  // (what is there is delivered; only the queue behind it can be discarded).
  size_t capacity = 0;
  {
    Pty probe;
    SerialTransport t(probe.path, false);
    t.open();
    const std::string chunk(256, 'x');
    try {
      for (int i = 0; i < 1000; ++i) t.write(chunk.data(), chunk.size());
    } catch (const ddace::Error&) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    capacity = fionread(probe.master);
  }
  ASSERT_GT(capacity, 54u);
  const Address address = *Address::parse("0000000000AA");
  Effector e;
  // Shift the lines against the queue's end until one goes out only in part.
  for (size_t shift = 0; shift < 54; ++shift) {
    Pty pty;
    SerialTransport t(pty.path, false);
    t.open();
    // Fill the far side with one whole (junk) line, then queue lines behind it.
    std::string filler(capacity - 1, 'x');
    filler += '\r';
    ASSERT_EQ(::write(t.fd(), filler.data(), filler.size()), static_cast<ssize_t>(filler.size()));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ASSERT_EQ(fionread(pty.master), capacity);
    const std::string pad(shift, 'y');
    ASSERT_EQ(::write(t.fd(), pad.data(), pad.size()), static_cast<ssize_t>(pad.size()));
    std::string error;
    for (int i = 0; i < 100000 && error.empty(); ++i) {
      e.left_wheel = static_cast<int8_t>(i % 100);
      const std::string line = encodeLine(encodeEffector(Model::Hamster, e), address);
      try {
        t.write(line.data(), line.size());
      } catch (const ddace::Error& err) {
        error = err.what();
      }
    }
    ASSERT_FALSE(error.empty());
    if (error.find("fragment discarded") == std::string::npos) continue;  // the queue ended at a line end
    EXPECT_EQ(drain(pty.master), filler);  // the queue behind it was discarded, fragment included
    e.left_wheel = 42;
    const std::string next = encodeLine(encodeEffector(Model::Hamster, e), address);
    t.write(next.data(), next.size());
    EXPECT_EQ(drain(pty.master), next);
    return;
  }
  FAIL() << "no write went out in part";
}

TEST_F(LinkTest, ARehearsalDrivesOnlyTheLinksOfItsOwnMockHoldingTheirDirectory) {
  // A rehearsal's bridge: only pseudo-terminal links in the mock's directory, and only while
  // this run's mock (here: this process) holds the directory's claim. A link nobody claims
  // (a crashed run's, someone's file) or one another process holds is never opened.
  MockRobot& m = addMock("a", "0000000000AA", Model::Hamster, 0.002);
  long mock_pid = ::getpid() + 1;  // first: another process's mock
  BridgeConfig bridge;
  RobotConfig r;
  r.name = "R1";
  r.address = *Address::parse("0000000000AA");
  r.port_hints = {"/dev/ttyUSB0"};  // a real dongle: never tried in a rehearsal
  r.transport = TransportKind::Ble;
  r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.002;
  bridge.robots = {r};
  useMockLinks(bridge, dir_);
  ASSERT_TRUE(bridge.robots[0].port_hints.empty());
  ASSERT_EQ(bridge.robots[0].transport, TransportKind::Serial);
  links_.push_back(std::make_unique<RobotLink>(bridge.robots[0], bridge, ports_,
                                               mockLinkTransportFactory(
                                                   dir_, [&] { return mock_pid; }, true)));
  RobotLink& link = *links_.back();
  commands_ = {{&link, 0.06, 0.06}};
  runFor(0.5);
  EXPECT_EQ(link.state(), LinkState::Searching);
  EXPECT_EQ(m.motoringLines(), 0u);
  EXPECT_NE(link.stats().last_error.find("is not claimed by a running mock Hamster node"), std::string::npos)
      << link.stats().last_error;

  auto claim = std::make_unique<LinkDirClaim>(dir_, std::vector<std::string>{}, "test");
  runFor(0.5);
  EXPECT_EQ(m.motoringLines(), 0u);
  EXPECT_NE(link.stats().last_error.find("not by this run's mock Hamster node"), std::string::npos)
      << link.stats().last_error;

  mock_pid = ::getpid();
  ASSERT_TRUE(runUntil([&] { return m.leftUnits() == 30; }, 5.0)) << link.stats().last_error;
  EXPECT_EQ(link.port(), dir_ + "/hamster_a");

  // A link in the directory that leads elsewhere than a pseudo-terminal, or a port outside it.
  std::filesystem::create_symlink("/dev/null", dir_ + "/hamster_b");
  EXPECT_NE(mockLinkProblem(dir_, dir_ + "/hamster_b", mock_pid).find("not to a mock Hamster's pseudo-terminal"),
            std::string::npos);
  EXPECT_NE(mockLinkProblem(dir_, "/dev/ttyUSB0", mock_pid).find("not in the mock link directory"), std::string::npos);
  EXPECT_EQ(mockLinkProblem(dir_, dir_ + "/hamster_a", mock_pid), "");
  claim.reset();
  EXPECT_FALSE(claimHolder(dir_).has_value());
}
