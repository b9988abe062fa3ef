#include "ddace/hamster/scan.h"

#include <chrono>
#include <memory>
#include <thread>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"

namespace ddace::hamster {

std::string surveyStatusName(PortSurvey::Status status) {
  switch (status) {
    case PortSurvey::Status::Robot:
      return "robot";
    case PortSurvey::Status::NoRobot:
      return "no robot linked";
    case PortSurvey::Status::NoReply:
      return "no reply";
    case PortSurvey::Status::OpenFailed:
      return "cannot open";
  }
  return "?";
}

std::vector<PortSurvey> surveyPorts(const std::vector<std::string>& patterns, const std::string& port_dir,
                                    double timeout_s, const TransportFactory& factory) {
  struct Probe {
    std::unique_ptr<Transport> transport;
    LineAssembler assembler;
    bool done = false;
  };
  std::vector<PortSurvey> out;
  std::vector<Probe> probes;
  for (const auto& port : expandPorts(patterns, port_dir)) {
    PortSurvey s;
    s.port = port;
    Probe p;
    p.transport = factory(port);
    try {
      p.transport->open();
    } catch (const Error& e) {
      s.status = PortSurvey::Status::OpenFailed;
      s.error = e.what();
      p.done = true;
    }
    out.push_back(s);
    probes.push_back(std::move(p));
  }
  const double start_s = monotonicS();
  double next_ff_s = start_s;
  char buf[512];
  for (;;) {
    const double now_s = monotonicS();
    bool all_done = true;
    for (size_t i = 0; i < probes.size(); ++i) {
      Probe& p = probes[i];
      if (p.done) continue;
      PortSurvey& s = out[i];
      try {
        if (now_s >= next_ff_s) p.transport->write(kIdentifyRequest.data(), kIdentifyRequest.size());
        for (size_t n; (n = p.transport->read(buf, sizeof buf)) > 0;) {
          p.assembler.push(buf, n, [&](std::string_view line) {
            const ParsedLine parsed = parseLine(line);
            if (parsed.kind == LineKind::Identify) {
              s.status = PortSurvey::Status::Robot;
              s.identified = true;
              s.identify = parsed.identify;
              p.done = true;
            } else if (parsed.kind == LineKind::Data && !s.identified) {
              s.status = PortSurvey::Status::Robot;
              s.identify.address = parsed.address;
            } else if (parsed.kind == LineKind::NoRobot && s.status == PortSurvey::Status::NoReply) {
              s.status = PortSurvey::Status::NoRobot;
            }
          });
          if (p.done) break;
        }
      } catch (const Error& e) {
        s.error = e.what();
        p.done = true;
      }
      all_done = all_done && p.done;
    }
    if (now_s >= next_ff_s) next_ff_s = now_s + 0.1;
    if (all_done || now_s - start_s >= timeout_s) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  for (auto& p : probes) p.transport->close();
  return out;
}

}  // namespace ddace::hamster
