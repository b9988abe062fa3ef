// The execution parameters of a config/execution.yaml, as the closed-loop simulator reads
// them (`ddace eval --execution diffdrive --config FILE`): the robots' path follower and
// safety filter, the simulated Hamster and the simulated table, under the same keys as the
// ROS nodes read them (each struct's visitParams() is the one list of names).
//
// Read: path_follower/gains, path_follower/safety, mock_robots/robot and mock_robots'
// bodies, object_speed_mps, object_damping_hz. A section or key that is absent (or a
// section whose keys are all commented out) keeps the built-in default (the shipped file
// states them all). An unknown key in path_follower, gains, safety, mock_robots or robot is an
// error; the other keys of path_follower and mock_robots are the nodes' own (known, not
// read here), and the other nodes' sections are not read nor checked here (the
// params_defaults rostest holds the shipped file's keys to the nodes'). The simulated Hamster's tracking noise and its
// seed are read but eval's are its own (--noise, --seed); gains/stop_radius_m is the task's stop radius, as segments
// carry it; `bodies: false` is refused (eval's points take no config). Units: metres, seconds, radians, as the file
// states them.
#pragma once

#include <string>

#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/exec/table_simulator.h"

namespace ddace::exec {

struct ExecutionConfig {
  FollowerGains gains;                          ///< path_follower/gains
  SafetyParams safety;                          ///< path_follower/safety
  DiffDriveParams robot = simulatedHamster();   ///< mock_robots/robot
  TableSimulatorParams table{/*bodies=*/true};  ///< mock_robots (the mock table has bodies)
};

/// Parses `text` (the contents of `file`, which the diagnostics name). Throws ddace::Error
/// with every problem at its file:line:column: a mistyped value, a key of gains, safety or
/// robot that is no parameter (a typo would silently change nothing), a value that
/// validate() refuses (at its section, naming the field), a file with neither
/// path_follower nor mock_robots.
ExecutionConfig parseExecutionConfig(const std::string& text, const std::string& file);
/// Reads and parses the file at `path`.
ExecutionConfig readExecutionConfig(const std::string& path);

}  // namespace ddace::exec
