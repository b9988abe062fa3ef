// LinkDirClaim: see include/ddace/hamster/link_dir.h.
#include "ddace/hamster/link_dir.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
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

}  // namespace ddace::hamster
