// ddace hamster-scan: list the Hamster dongles and the robot (model, address) on each.
#include <cstdio>
#include <iostream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/hamster/scan.h"

namespace ddace::cli {
namespace {

int runHamsterScan(const std::vector<std::string>& argv) {
  Args args(argv, {"--port-dir", "--timeout"}, {"--no-rtscts"});
  std::vector<std::string> patterns = args.positional();
  if (patterns.empty()) patterns = hamster::defaultScanPatterns();
  const std::string port_dir = args.get("--port-dir", "/dev");
  const double timeout_s = args.getDouble("--timeout", 1.5);
  if (!(timeout_s > 0)) throw Error("--timeout must be > 0 seconds");
  const auto survey =
      hamster::surveyPorts(patterns, port_dir, timeout_s, hamster::serialTransportFactory(!args.has("--no-rtscts")));
  if (survey.empty()) {
    std::cerr << "hamster-scan: no port matches";
    for (const auto& p : patterns) std::cerr << " " << (p[0] == '/' ? p : port_dir + "/" + p);
    std::cerr << "\n";
    return 1;
  }
  int robots = 0;
  for (const auto& s : survey) {
    std::cout << s.port << ": " << hamster::surveyStatusName(s.status);
    if (s.status == hamster::PortSurvey::Status::Robot) {
      ++robots;
      std::cout << ", address " << s.identify.address.display() << " (wire " << s.identify.address.wire() << ")";
      if (s.identified) {
        std::cout << ", model " << hamster::modelName(s.identify.model) << " (code " << std::hex
                  << int(s.identify.model_code) << std::dec << ", name '" << s.identify.name << "')";
      }
    }
    if (!s.error.empty()) std::cout << " [" << s.error << "]";
    std::cout << "\n";
  }
  std::cout << robots << " robot(s) found on " << survey.size() << " port(s)\n";
  return 0;
}

DDACE_COMMAND({"hamster-scan", "ddace hamster-scan [PATTERN...] [--port-dir /dev] [--timeout 1.5] [--no-rtscts]",
               "list Hamster dongles and the address/model of the robot on each (sends only FF)", runHamsterScan});

}  // namespace
}  // namespace ddace::cli
