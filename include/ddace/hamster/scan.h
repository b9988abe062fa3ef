// Which robot is on which dongle: probe serial ports with "FF" and report what answers.
//
// Owns: the one-shot survey behind `ddace hamster-scan` (to fill config/hamsters.yaml).
// Must not: keep ports open after returning, or drive anything (it sends only "FF").
#pragma once

#include <string>
#include <vector>

#include "ddace/hamster/protocol.h"
#include "ddace/hamster/transport.h"

namespace ddace::hamster {

struct PortSurvey {
  enum class Status {
    Robot,       ///< a robot answered (identify is set), or streamed lines (address known, model not)
    NoRobot,     ///< a dongle without a linked robot ("no robot" lines)
    NoReply,     ///< opened, but nothing recognisable within the timeout
    OpenFailed,  ///< could not be opened as a serial port (error says why)
  };
  std::string port;
  Status status = Status::NoReply;
  bool identified = false;  ///< identify came from an FF reply (else only the address from data lines)
  IdentifyReply identify;
  std::string error;
};

/// "robot", "no robot linked", "no reply", "cannot open".
std::string surveyStatusName(PortSurvey::Status status);

/// Opens every port matching `patterns` (see expandPorts) at once, sends "FF\r" every
/// 100 ms and listens for up to timeout_s; returns one entry per port, in port order.
std::vector<PortSurvey> surveyPorts(const std::vector<std::string>& patterns, const std::string& port_dir,
                                    double timeout_s, const TransportFactory& factory);

}  // namespace ddace::hamster
