// Benchmark of the Hamster bridge's per-line work and its command-to-wire latency.
//
// 1. CPU time per handled sensor line with 8 robots: 8 RobotLinks over in-memory
//    transports, each fed sensor lines; every line is read, reassembled, validated,
//    decoded, and answered with one motoring line. Reported as µs per line and as a
//    ratio to a reference measured in the same run: the bare protocol work for one
//    line (parseLine + decodeSensors + encodeEffector + encodeLine), i.e. the overhead
//    of the link state machine, transport calls and bookkeeping. Goal: < 20 µs/line.
// 2. Command-to-wire latency, in cycles: a new command is set between two sensor
//    lines; the bench checks which motoring line first carries it. Goal: the next one.
// 3. The same latency end to end over pseudo-terminals (8 mock robots, 50 Hz sensor
//    lines): wall time from setWheelCommand until the mock robot decodes the new
//    units, as a ratio to the 20 ms sensor period.
// Writes docs/bench/hamster_link.md.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numeric>
#include <sstream>
#include <thread>

#include "ddace/common/clock.h"
#include "ddace/hamster/link.h"
#include "ddace/hamster/mock_robot.h"
#include "results.h"

using namespace ddace::hamster;
using ddace::monotonicS;
using ddace::threadCpuS;

namespace {

/// A dongle in memory: the bench writes robot lines into `in`, the link's replies land in `out`.
struct Pipe {
  std::string in;
  std::string out;
  size_t lines_out = 0;
};

class MemoryTransport : public Transport {
 public:
  MemoryTransport(std::string name, std::shared_ptr<Pipe> pipe) : name_(std::move(name)), pipe_(std::move(pipe)) {}
  void open() override { open_ = true; }
  void close() override { open_ = false; }
  bool isOpen() const override { return open_; }
  size_t read(char* buf, size_t size) override {
    const size_t n = std::min(size, pipe_->in.size());
    std::copy_n(pipe_->in.data(), n, buf);
    pipe_->in.erase(0, n);
    return n;
  }
  void write(const char* data, size_t size) override {
    pipe_->out.append(data, size);
    ++pipe_->lines_out;
  }
  void flush() override { pipe_->in.clear(); }
  std::string name() const override { return name_; }

 private:
  std::string name_;
  std::shared_ptr<Pipe> pipe_;
  bool open_ = false;
};

Address addressOf(int i) {
  Address a;
  a.bytes[5] = static_cast<uint8_t>(0xB0 + i);
  return a;
}

std::string sensorLine(int robot, Model model, int k) {
  Sensors s;
  s.proximity_left = static_cast<uint8_t>(k);
  s.accel_z = 16384;
  s.battery_v = 3.9;
  return encodeLine(encodeSensors(model, s, k % 2 == 0), addressOf(robot));
}

struct CpuResult {
  double link_us = 0, reference_us = 0;
  long lines = 0;
  int latency_max_cycles = 0;
  long latency_checks = 0;
};

CpuResult cpuBench(int robots, long cycles) {
  BridgeConfig bridge;
  bridge.port_dir = "/nonexistent";
  std::vector<std::shared_ptr<Pipe>> pipes;
  std::vector<std::unique_ptr<RobotLink>> links;
  std::vector<Model> models;
  std::vector<CycleReport> reports;
  CpuResult result;
  // Every link needs an existing candidate path: the bench executable itself (the
  // memory factory never opens it). Each link gets its own PortDirectory so the
  // shared path does not block the others.
  const std::string exe = std::filesystem::read_symlink("/proc/self/exe").string();
  for (int i = 0; i < robots; ++i) {
    auto pipe = std::make_shared<Pipe>();
    pipes.push_back(pipe);
    models.push_back(i % 2 ? Model::HamsterS : Model::Hamster);
    RobotConfig r;
    r.name = "R" + std::to_string(i + 1);
    r.address = addressOf(i);
    r.port_hints = {exe};
    r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.001;
    links.push_back(std::make_unique<RobotLink>(
        r, bridge, std::make_shared<PortDirectory>(),
        [pipe](const std::string& p) { return std::make_unique<MemoryTransport>(p, pipe); }));
  }
  double t = 0.0;
  for (int i = 0; i < robots; ++i) {
    links[i]->poll(t, reports);  // opens, sends FF
    IdentifyReply reply;
    reply.name = "Hamster";
    reply.model = models[i];
    reply.model_code = static_cast<uint8_t>(models[i]);
    reply.info = "01";
    reply.address = addressOf(i);
    pipes[i]->in += encodeIdentifyReply(reply) + "\r";
    links[i]->poll(t, reports);
    if (links[i]->state() != LinkState::Streaming) {
      std::cerr << "bench: link " << i << " did not reach streaming: " << links[i]->stats().last_error << "\n";
      std::exit(1);
    }
  }
  // Pre-encode the robot lines (the robot's work is not the bridge's).
  std::vector<std::vector<std::string>> lines(robots);
  for (int i = 0; i < robots; ++i) {
    for (int k = 0; k < 64; ++k) lines[i].push_back(sensorLine(i, models[i], k));
  }
  // Link: the full per-line path.
  reports.reserve(robots);
  const double c0 = threadCpuS();
  for (long c = 0; c < cycles; ++c) {
    t += 0.02;
    for (int i = 0; i < robots; ++i) {
      // A new command every 7th cycle; check below that the very next reply carries it.
      if (c % 7 == 0) links[i]->setWheelCommand(0.001 * static_cast<double>(c % 100), -0.05, t);
      pipes[i]->in += lines[i][c % 64];
      reports.clear();
      links[i]->poll(t, reports);
      if (c % 7 == 0) {
        const ParsedLine sent = parseLine(std::string_view(pipes[i]->out).substr(pipes[i]->out.size() - 54, 53));
        const auto e = decodeEffector(models[i], sent.payload);
        const int want = static_cast<int>(c % 100);
        ++result.latency_checks;
        if (!e || e->left_wheel != want) result.latency_max_cycles = std::max(result.latency_max_cycles, 2);
        else result.latency_max_cycles = std::max(result.latency_max_cycles, 1);
      }
      if (pipes[i]->out.size() > (1 << 16)) pipes[i]->out.clear();
    }
  }
  const double c1 = threadCpuS();
  result.lines = cycles * robots;
  for (int i = 0; i < robots; ++i) {
    if (links[i]->stats().lines_ok != static_cast<uint64_t>(cycles) || links[i]->stats().lines_dropped != 0) {
      std::cerr << "bench: link " << i << " handled " << links[i]->stats().lines_ok << " of " << cycles << " lines\n";
      std::exit(1);
    }
  }
  // Reference: the protocol work alone for the same lines.
  Effector e;
  e.left_wheel = 10;
  size_t sink = 0;
  const double r0 = threadCpuS();
  for (long c = 0; c < cycles; ++c) {
    for (int i = 0; i < robots; ++i) {
      const std::string& l = lines[i][c % 64];
      const ParsedLine p = parseLine(std::string_view(l).substr(0, 53));
      const auto s = decodeSensors(models[i], p.payload);
      const std::string out = encodeLine(encodeEffector(models[i], e), p.address);
      sink += out.size() + (s ? s->proximity_left : 0);
    }
  }
  const double r1 = threadCpuS();
  if (sink == 0) std::exit(1);
  result.link_us = (c1 - c0) / static_cast<double>(result.lines) * 1e6;
  result.reference_us = (r1 - r0) / static_cast<double>(result.lines) * 1e6;
  return result;
}

struct PtyResult {
  double mean_ms = 0, p95_ms = 0, max_ms = 0;
  int samples = 0;
  double period_ms = 20.0;
  long lines = 0;
  double link_cpu_us_per_line = 0;  ///< CPU of the polls that handled lines, incl. system calls, per line
  long idle_polls = 0;
  double idle_us_per_poll = 0;  ///< CPU of a poll that found no line (one read system call)
};

PtyResult ptyBench(int robots, int commands) {
  char tmpl[] = "/tmp/ddace_hamster_bench_XXXXXX";
  if (!::mkdtemp(tmpl)) std::exit(1);
  const std::string dir = tmpl;
  std::vector<std::unique_ptr<MockRobot>> mocks;
  std::vector<std::unique_ptr<RobotLink>> links;
  BridgeConfig bridge;
  bridge.port_dir = dir;
  bridge.scan = {};
  auto ports = std::make_shared<PortDirectory>();
  for (int i = 0; i < robots; ++i) {
    MockRobotSettings s;
    s.name = "R" + std::to_string(i + 1);
    s.address = addressOf(i);
    s.model = i % 2 ? Model::HamsterS : Model::Hamster;
    s.link_path = dir + "/hamster_" + s.name;
    mocks.push_back(std::make_unique<MockRobot>(s));
    RobotConfig r;
    r.name = s.name;
    r.address = s.address;
    r.port_hints = {"hamster_" + s.name};
    r.calibration.left_mps_per_unit = r.calibration.right_mps_per_unit = 0.001;
    links.push_back(std::make_unique<RobotLink>(r, bridge, ports, serialTransportFactory()));
  }
  std::vector<CycleReport> reports;
  double link_cpu_s = 0.0, idle_cpu_s = 0.0;
  long idle_polls = 0;
  auto step = [&](double now) {
    for (auto& m : mocks) m->step(now);
    for (auto& l : links) {
      const uint64_t before = l->stats().lines_ok;
      const double c0 = threadCpuS();
      l->poll(now, reports);
      const double c1 = threadCpuS();
      if (l->stats().lines_ok > before) {
        link_cpu_s += c1 - c0;
      } else {
        idle_cpu_s += c1 - c0;
        ++idle_polls;
      }
    }
    reports.clear();
  };
  // Connect and settle.
  const double start = monotonicS();
  while (monotonicS() - start < 5.0) {
    step(monotonicS());
    bool all = true;
    for (auto& l : links) all = all && l->state() == LinkState::Streaming;
    if (all) break;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  std::vector<double> latencies;
  link_cpu_s = idle_cpu_s = 0.0;
  idle_polls = 0;
  uint64_t lines_before = 0;
  for (auto& l : links) lines_before += l->stats().lines_ok;
  for (int k = 0; k < commands; ++k) {
    const int units = (k % 2 ? 40 : -40) + k % 7;
    std::vector<double> issued(robots), seen(robots, -1.0);
    const double t_cmd = monotonicS();
    for (int i = 0; i < robots; ++i) {
      links[i]->setWheelCommand(units * 0.001, units * 0.001, t_cmd);
      issued[i] = t_cmd;
    }
    // Keep the command fresh while waiting (like a 50 Hz publisher), up to 0.1 s.
    while (monotonicS() - t_cmd < 0.1) {
      const double now = monotonicS();
      for (int i = 0; i < robots; ++i) links[i]->setWheelCommand(units * 0.001, units * 0.001, now);
      step(now);
      for (int i = 0; i < robots; ++i) {
        if (seen[i] < 0 && mocks[i]->leftUnits() == units) seen[i] = monotonicS();
      }
      if (std::all_of(seen.begin(), seen.end(), [](double s) { return s >= 0; })) break;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    for (int i = 0; i < robots; ++i) {
      if (seen[i] >= 0) latencies.push_back((seen[i] - issued[i]) * 1e3);
    }
    // Random phase for the next command relative to the 20 ms sensor cycle.
    const double pause = 0.005 + 0.003 * (k % 5);
    const double until = monotonicS() + pause;
    while (monotonicS() < until) {
      step(monotonicS());
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  uint64_t lines_after = 0;
  for (auto& l : links) lines_after += l->stats().lines_ok;
  links.clear();
  mocks.clear();
  std::filesystem::remove_all(dir);
  PtyResult r;
  r.lines = static_cast<long>(lines_after - lines_before);
  r.link_cpu_us_per_line = r.lines > 0 ? link_cpu_s / static_cast<double>(r.lines) * 1e6 : 0.0;
  r.idle_polls = idle_polls;
  r.idle_us_per_poll = idle_polls > 0 ? idle_cpu_s / static_cast<double>(idle_polls) * 1e6 : 0.0;
  r.samples = static_cast<int>(latencies.size());
  if (latencies.empty()) return r;
  std::sort(latencies.begin(), latencies.end());
  r.mean_ms = std::accumulate(latencies.begin(), latencies.end(), 0.0) / latencies.size();
  r.p95_ms = latencies[static_cast<size_t>(0.95 * (latencies.size() - 1))];
  r.max_ms = latencies.back();
  return r;
}

}  // namespace

int main(int argc, char** argv) try {
  const std::filesystem::path repo = ddace::bench::repositoryFromArgs(argc, argv);
  if (argc > 1) {
    std::cerr << "usage: bench_hamster_link [--repo DIR]\n";
    return 2;
  }
  const int robots = 8;
  const long cycles = 50000;
  const CpuResult cpu = cpuBench(robots, cycles);
  const int commands = 60;
  const PtyResult pty = ptyBench(robots, commands);

  std::ostringstream md;
  char buf[512];
  md << "# Hamster bridge: CPU per line and command-to-wire latency\n\n"
     << "Produced by `ddace bench hamster_link` (bench/hamster_link.cpp). Timings depend on the machine;\n"
     << "the ratios compare against references measured in the same run.\n\n"
     << "## CPU time per handled sensor line, " << robots << " robots\n\n"
     << "Each line is read from the transport, reassembled, validated, decoded and answered with one\n"
     << "motoring line by `RobotLink::poll` (in-memory transports, so no system calls).\n"
     << "Reference: the bare protocol work for the same line (parse + decode + encode).\n\n"
     << "| lines | µs per line (link) | µs per line (reference) | ratio link / reference | goal |\n"
     << "|---|---|---|---|---|\n";
  std::snprintf(buf, sizeof buf, "| %ld | %.3f | %.3f | %.2f | < 20 µs/line: %s |\n", cpu.lines, cpu.link_us,
                cpu.reference_us, cpu.link_us / cpu.reference_us, cpu.link_us < 20.0 ? "met" : "NOT met");
  md << buf << "\n## Command-to-wire latency in cycles\n\n";
  std::snprintf(buf, sizeof buf,
                "%ld new commands set between two sensor lines; the latest cycle that first carried one: "
                "%d (1 = the very next motoring line). Goal: the next cycle: %s.\n\n",
                cpu.latency_checks, cpu.latency_max_cycles, cpu.latency_max_cycles == 1 ? "met" : "NOT met");
  md << buf << "## Command-to-wire latency over pseudo-terminals\n\n"
     << robots << " mock robots (`MockRobot`) streaming sensor lines every 20 ms; time from\n"
     << "`setWheelCommand` until the mock robot has decoded the new wheel units. A command waits for the\n"
     << "next sensor line (the protocol is response-driven), so the expected mean is about half a period.\n\n"
     << "| samples | mean ms | p95 ms | max ms | mean / sensor period |\n|---|---|---|---|---|\n";
  std::snprintf(buf, sizeof buf, "| %d | %.2f | %.2f | %.2f | %.2f |\n", pty.samples, pty.mean_ms, pty.p95_ms,
                pty.max_ms, pty.mean_ms / pty.period_ms);
  md << buf << "\nCPU time of `RobotLink::poll` on the real pseudo-terminals (thread CPU clock, so the\n"
     << "read/write system calls are included). Polls that handled a line are charged to that line;\n"
     << "polls that found nothing are the idle cost (hamster_bridge_node polls every port whenever any\n"
     << "port has data, and at least every 2 ms).\n\n"
     << "| lines | µs CPU per line (link + syscalls) | ratio to the in-memory link | goal | idle polls | µs CPU per "
        "idle poll |\n"
     << "|---|---|---|---|---|---|\n";
  std::snprintf(buf, sizeof buf, "| %ld | %.2f | %.1f | < 20 µs/line: %s | %ld | %.2f |\n", pty.lines,
                pty.link_cpu_us_per_line, pty.link_cpu_us_per_line / cpu.link_us,
                pty.link_cpu_us_per_line < 20.0 ? "met" : "NOT met", pty.idle_polls, pty.idle_us_per_poll);
  md << buf;
  std::cout << md.str();
  ddace::bench::writeResults(repo, "hamster_link", md.str());
  return cpu.latency_max_cycles == 1 && pty.samples == robots * commands ? 0 : 1;
} catch (const std::exception& e) {
  std::cerr << "bench_hamster_link: error: " << e.what() << "\n";
  return 1;
}
