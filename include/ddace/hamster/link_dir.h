// The directory of pseudo-terminal links through which the mock Hamsters of one run and
// that run's bridge find each other (<dir>/hamster_<name>).
//
// Owns: the claim of one run on that directory. Two runs sharing it would let the bridge of
// one drive the mock robots of the other, so a claim is an exclusive lock on a lock file in
// the directory, held for the run's lifetime (the kernel releases it when the process dies,
// so a crashed run never blocks the next one). A claim refuses a directory that already
// holds a link it would create: a crashed run's stale link or a user's file is never
// replaced. Released, it removes only what it created: its lock file, and the directory
// when it created it and nothing else is left in it.
// Must not: delete or replace a file it did not create, or touch ROS.
#pragma once

#include <string>
#include <vector>

namespace ddace::hamster {

class LinkDirClaim {
 public:
  /// Claims `dir` (created when missing, its parent must exist) for links named
  /// `link_names`. Throws ddace::Error naming `dir` and `parameter` (e.g. the launch
  /// argument that chose it) when the directory cannot be created, another live process
  /// holds it (its pid in the message), or one of `link_names` exists in it already.
  LinkDirClaim(const std::string& dir, const std::vector<std::string>& link_names, const std::string& parameter);
  ~LinkDirClaim();
  LinkDirClaim(const LinkDirClaim&) = delete;
  LinkDirClaim& operator=(const LinkDirClaim&) = delete;

  const std::string& dir() const { return dir_; }
  /// The lock file's name inside the directory.
  static const char* lockFileName();

 private:
  void release();

  std::string dir_;
  int lock_fd_ = -1;
  bool created_dir_ = false;
  bool created_lock_ = false;
};

}  // namespace ddace::hamster
