#include <fcntl.h>
#include <glob.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <set>

#include "ddace/common/error.h"
#include "ddace/hamster/transport.h"

namespace ddace::hamster {
namespace {

std::string osError(const std::string& what, const std::string& path) {
  return what + " " + path + ": " + std::strerror(errno);
}

}  // namespace

SerialTransport::SerialTransport(std::string path, bool rtscts) : path_(std::move(path)), rtscts_(rtscts) {}

SerialTransport::~SerialTransport() {
  close();
}

void SerialTransport::open() {
  close();
  const int fd = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw Error(osError("cannot open serial port", path_));
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) {
    const std::string msg = osError("not a serial port (tcgetattr)", path_);
    ::close(fd);
    throw Error(msg);
  }
  // Raw bytes: no echo, no CR/LF translation (the protocol's line end is CR).
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | PARENB | CSIZE);
  tio.c_cflag |= CS8;
  if (rtscts_) {
    tio.c_cflag |= CRTSCTS;
  } else {
    tio.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS);
  }
  tio.c_cc[VMIN] = 1;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, B115200);
  ::cfsetospeed(&tio, B115200);
  if (::tcsetattr(fd, TCSANOW, &tio) != 0) {
    const std::string msg = osError("cannot configure 115200 8N1 RTS/CTS on", path_);
    ::close(fd);
    throw Error(msg);
  }
  // Exclusive: a second opener (another bridge) gets EBUSY instead of stealing lines.
  ::ioctl(fd, TIOCEXCL);
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
}

void SerialTransport::close() {
  if (fd_ >= 0) {
    ::ioctl(fd_, TIOCNXCL);
    ::close(fd_);
    fd_ = -1;
  }
}

size_t SerialTransport::read(char* buf, size_t size) {
  if (fd_ < 0) throw Error("serial port " + path_ + " is not open");
  const ssize_t n = ::read(fd_, buf, size);
  if (n > 0) return static_cast<size_t>(n);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
  // VMIN=1 with O_NONBLOCK: "no data" is EAGAIN, so 0 (end of file) only comes after a
  // hang-up (adapter unplugged); EIO when a pty's other side closed.
  if (n == 0) throw Error("serial port " + path_ + " hung up (unplugged?)");
  throw Error(osError("read failed on", path_));
}

void SerialTransport::write(const char* data, size_t size) {
  if (fd_ < 0) throw Error("serial port " + path_ + " is not open");
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd_, data + done, size - done);
    if (n > 0) {
      done += static_cast<size_t>(n);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      if (done > 0) {
        // A fragment is queued: sent later, it would run into the next line and the
        // dongle would get one malformed line. Discard the whole unsent output.
        ::tcflush(fd_, TCOFLUSH);
        throw Error("serial port " + path_ + ": output queue full (flow control) after " + std::to_string(done) +
                    " of " + std::to_string(size) + " bytes; fragment discarded");
      }
      throw Error("serial port " + path_ + ": output queue full (flow control), line dropped");
    } else {
      throw Error(osError("write failed on", path_));
    }
  }
}

void SerialTransport::flush() {
  if (fd_ >= 0) ::tcflush(fd_, TCIOFLUSH);
}

TransportFactory serialTransportFactory(bool rtscts) {
  return [rtscts](const std::string& port) { return std::make_unique<SerialTransport>(port, rtscts); };
}

std::vector<std::string> defaultScanPatterns() {
  return {"serial/by-id/*", "ttyUSB*", "ttyACM*"};
}

std::string canonicalPort(const std::string& path) {
  char resolved[PATH_MAX];
  if (::realpath(path.c_str(), resolved)) return resolved;
  return path;
}

std::vector<std::string> expandPorts(const std::vector<std::string>& patterns, const std::string& port_dir) {
  std::vector<std::string> out;
  std::set<std::string> seen;
  for (const auto& pattern : patterns) {
    if (pattern.empty()) continue;
    std::string full = pattern;
    if (pattern[0] != '/') full = (port_dir.empty() ? std::string("/dev") : port_dir) + "/" + pattern;
    glob_t g{};
    if (::glob(full.c_str(), 0, nullptr, &g) == 0) {
      std::vector<std::string> found(g.gl_pathv, g.gl_pathv + g.gl_pathc);
      std::sort(found.begin(), found.end());
      for (const auto& path : found) {
        if (seen.insert(canonicalPort(path)).second) out.push_back(path);
      }
    }
    ::globfree(&g);
  }
  return out;
}

std::string bleEndpoint(const std::string& adapter, const Address& address) {
  return "ble:" + adapter + "/" + address.display();
}

bool parseBleEndpoint(const std::string& port, std::string* adapter, Address* address) {
  const size_t slash = port.find('/');
  if (port.rfind("ble:", 0) != 0 || slash == std::string::npos || slash == 4) return false;
  const std::string name = port.substr(4, slash - 4);
  // The adapter becomes a D-Bus object path element (/org/bluez/<adapter>).
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  }
  const auto a = Address::parse(port.substr(slash + 1));
  if (!a) return false;
  *adapter = name;
  *address = *a;
  return true;
}

}  // namespace ddace::hamster
