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

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "ddace/hamster/config.h"
#include "ddace/hamster/transport.h"

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

/// The pid that the live process holding `dir`'s claim wrote; nullopt when no live process
/// holds it (no lock file, or its lock is free: the run that claimed it has ended).
std::optional<long> claimHolder(const std::string& dir);

/// The bridge of a run whose robots are mock Hamsters (a rehearsal) drives only that run's
/// mock links, never a real dongle and never another run's mocks: `config` reduced to the
/// links in `dir` (port_dir = dir, scan [hamster_*], no port hints, which could name a real
/// port, and every robot serial: a BLE robot is simulated behind a link too).
void useMockLinks(BridgeConfig& config, const std::string& dir);

/// Why `port` is not a mock Hamster link of the run whose mock holds `dir`'s claim as process
/// `mock_pid` (nullopt: that process is not known yet), or "" when it is: a path directly in
/// `dir`, the directory claimed by that live process, the port a pseudo-terminal.
std::string mockLinkProblem(const std::string& dir, const std::string& port, std::optional<long> mock_pid);

/// Serial transports for useMockLinks: opening a port for which mockLinkProblem() names a
/// problem throws that problem (the link keeps searching, its diagnostics say why).
/// `mock_pid` is asked on every open (the mock may start after the bridge).
TransportFactory mockLinkTransportFactory(const std::string& dir, std::function<std::optional<long>()> mock_pid,
                                          bool rtscts);

}  // namespace ddace::hamster
