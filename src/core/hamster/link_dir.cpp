// LinkDirClaim: see include/ddace/hamster/link_dir.h.
#include "ddace/hamster/link_dir.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "ddace/common/error.h"

namespace ddace::hamster {

namespace {

std::string holderOf(const std::string& lock_path) {
  std::ifstream in(lock_path);
  std::string pid;
  in >> pid;
  return pid.empty() ? "another process" : "process " + pid;
}

}  // namespace

const char* LinkDirClaim::lockFileName() {
  return ".ddace_mock_hamster.lock";
}

LinkDirClaim::LinkDirClaim(const std::string& dir, const std::vector<std::string>& link_names,
                           const std::string& parameter)
    : dir_(dir) {
  const std::string where = parameter + " " + dir;
  if (dir.empty()) throw Error(parameter + " is empty: give a directory for the mock Hamsters' pty links");
  if (::mkdir(dir.c_str(), 0700) == 0) {
    created_dir_ = true;
  } else if (errno != EEXIST) {
    throw Error("cannot create " + where + ": " + std::strerror(errno));
  }
  const std::string lock_path = dir + "/" + lockFileName();
  // A run that releases its claim removes the lock file: a lock taken on a file already
  // unlinked is no claim, so the lock is retaken on the file now at that path.
  for (int attempt = 0; lock_fd_ < 0; ++attempt) {
    int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    bool created = fd >= 0;
    if (!created && errno == EEXIST) fd = ::open(lock_path.c_str(), O_RDWR | O_CLOEXEC);
    if (fd < 0) {
      const std::string why = std::strerror(errno);
      release();
      throw Error("cannot open the lock file " + lock_path + " of " + where + ": " + why);
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd);
      const std::string holder = holderOf(lock_path);
      release();
      throw Error(where + " is in use by a live run (" + holder + " holds " + lock_path +
                  "; its bridge would drive this run's mock robots): give a directory no other run uses (the launch "
                  "files' default is one of its own per run)");
    }
    struct stat held {
    }, now{};
    if (::fstat(fd, &held) == 0 && ::stat(lock_path.c_str(), &now) == 0 && held.st_ino == now.st_ino &&
        held.st_dev == now.st_dev) {
      lock_fd_ = fd;
      created_lock_ = created;
    } else {
      ::close(fd);
      if (attempt >= 10) {
        release();
        throw Error("cannot lock " + lock_path + " of " + where + ": it keeps being replaced");
      }
    }
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(lock_fd_, 0) != 0 || ::write(lock_fd_, pid.data(), pid.size()) != static_cast<ssize_t>(pid.size())) {
    // Only the error message's holder pid is lost; the lock itself holds.
  }
  std::ostringstream present;
  for (const std::string& name : link_names) {
    struct stat st {};
    if (::lstat((dir + "/" + name).c_str(), &st) == 0) present << (present.tellp() > 0 ? ", " : "") << name;
  }
  if (present.tellp() > 0) {
    release();
    throw Error(where + " already holds " + present.str() +
                " (a link left by a run that crashed, or a file of yours): not replaced; remove "
                "them yourself or give another directory");
  }
}

LinkDirClaim::~LinkDirClaim() {
  release();
}

void LinkDirClaim::release() {
  if (lock_fd_ >= 0) {
    // Unlinked while still locked, so no other run can lock this file after it is gone.
    if (created_lock_) ::unlink((dir_ + "/" + lockFileName()).c_str());
    ::close(lock_fd_);
    lock_fd_ = -1;
  }
  if (created_dir_) ::rmdir(dir_.c_str());  // fails, and keeps it, unless it is empty
  created_dir_ = created_lock_ = false;
}

std::optional<long> claimHolder(const std::string& dir) {
  const std::string lock_path = dir + "/" + LinkDirClaim::lockFileName();
  const int fd = ::open(lock_path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  std::optional<long> holder;
  if (::flock(fd, LOCK_SH | LOCK_NB) == 0) {
    ::flock(fd, LOCK_UN);  // free: nobody holds the claim
  } else if (errno == EWOULDBLOCK) {
    char text[32] = {0};
    const ssize_t n = ::pread(fd, text, sizeof text - 1, 0);
    char* end = nullptr;
    const long pid = n > 0 ? std::strtol(text, &end, 10) : 0;
    holder = pid > 0 && end != text ? pid : -1;  // held, but by a pid it did not write (yet)
  }
  ::close(fd);
  return holder;
}

void useMockLinks(BridgeConfig& config, const std::string& dir) {
  config.port_dir = dir;
  config.scan = {"hamster_*"};
  for (RobotConfig& r : config.robots) {
    r.port_hints.clear();
    r.transport = TransportKind::Serial;
  }
}

std::string mockLinkProblem(const std::string& dir, const std::string& port, std::optional<long> mock_pid) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path in_dir = fs::weakly_canonical(fs::path(dir), ec);
  if (ec || fs::weakly_canonical(fs::path(port).parent_path(), ec) != in_dir || ec)
    return port + " is not in the mock link directory " + dir;
  if (!mock_pid) return "this run's mock Hamster node is not running yet (waiting for it before opening " + port + ")";
  const std::optional<long> holder = claimHolder(dir);
  if (!holder)
    return dir + " is not claimed by a running mock Hamster node (" + port +
           " may be a crashed run's link or someone else's file): not opened";
  if (*holder != *mock_pid)
    return dir + " is claimed by process " + std::to_string(*holder) + ", not by this run's mock Hamster node (pid " +
           std::to_string(*mock_pid) + "): another run's robots, not opened";
  char resolved[PATH_MAX];
  if (!::realpath(port.c_str(), resolved)) return "cannot resolve " + port + ": " + std::strerror(errno);
  if (std::string(resolved).rfind("/dev/pts/", 0) != 0)
    return port + " leads to " + resolved + ", not to a mock Hamster's pseudo-terminal: not opened";
  return "";
}

namespace {

/// A serial port opened only after mockLinkProblem() found none.
class MockLinkTransport : public SerialTransport {
 public:
  MockLinkTransport(std::string dir, std::string port, std::optional<long> mock_pid, bool rtscts)
      : SerialTransport(port, rtscts), dir_(std::move(dir)), mock_pid_(mock_pid) {}
  void open() override {
    const std::string problem = mockLinkProblem(dir_, name(), mock_pid_);
    if (!problem.empty()) throw Error(problem);
    SerialTransport::open();
  }

 private:
  std::string dir_;
  std::optional<long> mock_pid_;
};

}  // namespace

TransportFactory mockLinkTransportFactory(const std::string& dir, std::function<std::optional<long>()> mock_pid,
                                          bool rtscts) {
  return [dir, mock_pid = std::move(mock_pid), rtscts](const std::string& port) -> std::unique_ptr<Transport> {
    return std::make_unique<MockLinkTransport>(dir, port, mock_pid(), rtscts);
  };
}

}  // namespace ddace::hamster
