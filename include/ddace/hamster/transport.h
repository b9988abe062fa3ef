// Byte transports to a Hamster dongle, and finding candidate ports.
//
// Owns: the Transport interface (non-blocking open/read/write/close of one link),
// the POSIX serial implementation (termios raw 115200 8N1 with RTS/CTS hardware
// flow control), port discovery by glob patterns, and the names of direct-BLE
// endpoints (the BLE transport itself is ble_transport.h, built with DDACE_WITH_BLE).
// Must not: interpret the bytes (that is protocol.h) or decide which robot is where
// (that is link.h).
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ddace/hamster/protocol.h"

namespace ddace::hamster {

/// One byte link to one dongle. All calls are non-blocking.
class Transport {
 public:
  virtual ~Transport() = default;
  /// Opens the link. Throws ddace::Error naming the port and the OS error.
  virtual void open() = 0;
  virtual void close() = 0;
  virtual bool isOpen() const = 0;
  /// Reads what is available into buf (at most size bytes). Returns the number of
  /// bytes read (0 = nothing now). Throws ddace::Error when the link is gone
  /// (device unplugged, hang-up); the caller then closes and reopens.
  virtual size_t read(char* buf, size_t size) = 0;
  /// Writes all bytes or throws ddace::Error. A full output queue (flow control
  /// holding us back) throws too: a stale command must never be queued for later,
  /// and a line that went out only in part is discarded from the queue (TCOFLUSH),
  /// so the next line reaches the dongle whole.
  virtual void write(const char* data, size_t size) = 0;
  /// Drops unread input and unsent output.
  virtual void flush() = 0;
  /// File descriptor for poll(2), -1 when closed or not applicable.
  virtual int fd() const { return -1; }
  /// True while an opened link is still being established (a BLE connection in
  /// progress): reads return 0 and the caller waits instead of counting its
  /// identification requests. A transport that gives up throws from read().
  virtual bool connecting() const { return false; }
  /// Human-readable name (the port path).
  virtual std::string name() const = 0;
};

/// Creates a transport for a port path (not yet opened).
using TransportFactory = std::function<std::unique_ptr<Transport>(const std::string& port)>;

/// POSIX serial port: raw mode, 115200 baud, 8N1, CRTSCTS, O_NONBLOCK, exclusive
/// (TIOCEXCL) so two processes cannot share one dongle. Works on pseudo-terminals.
class SerialTransport : public Transport {
 public:
  explicit SerialTransport(std::string path, bool rtscts = true);
  ~SerialTransport() override;
  void open() override;
  void close() override;
  bool isOpen() const override { return fd_ >= 0; }
  size_t read(char* buf, size_t size) override;
  void write(const char* data, size_t size) override;
  void flush() override;
  int fd() const override { return fd_; }
  std::string name() const override { return path_; }

 private:
  std::string path_;
  bool rtscts_;
  int fd_ = -1;
};

/// The factory for SerialTransport.
TransportFactory serialTransportFactory(bool rtscts = true);

/// Default scan patterns, relative to the port directory: serial/by-id/*, ttyUSB*, ttyACM*.
std::vector<std::string> defaultScanPatterns();

/// Expands glob patterns (relative ones are taken relative to `port_dir`, usually
/// "/dev") into existing paths, in pattern order, sorted within a pattern, without
/// duplicates (two paths naming the same device, e.g. a by-id symlink and its
/// ttyUSB target, count once: the first one wins).
std::vector<std::string> expandPorts(const std::vector<std::string>& patterns, const std::string& port_dir);

/// The canonical device path (symlinks resolved); the path itself when it does not resolve.
std::string canonicalPort(const std::string& path);

/// The port name of a robot reached by direct BLE: "ble:<adapter>/<AA:BB:CC:DD:EE:FF>"
/// (address in the usual display order). RobotLink uses it as the robot's only
/// candidate port; bleTransportFactory() (ble_transport.h) parses it.
std::string bleEndpoint(const std::string& adapter, const Address& address);

/// Splits a bleEndpoint() name. False when `port` is not one.
bool parseBleEndpoint(const std::string& port, std::string* adapter, Address* address);

}  // namespace ddace::hamster
