// execution_monitor_node: watches a run and, when it ends — finished, aborted, e-stopped,
// timed out or interrupted (SIGINT) — writes its record: the executed step sequence next to
// the ground truth and the trial's metrics, scored through eval::scoreTrial (the same
// definition as `ddace eval`; docs/task-format.md), into a run directory, then ends the
// launch that started it (SIGINT to the parent roslaunch) so a run ends without a red
// "REQUIRED process has died".
//
// Run directory (`run_dir`, default `runs_dir`/<UTC timestamp>, `runs_dir` default
// $HOME/.ros/ddace/runs; `runs_dir`/latest points at the newest):
//   report.txt   the printed report          result.json  the metrics (eval's definitions)
//   run.json     planned paths (with stddev), executed positions, decision times
//   run.bag      entities, segments, statuses, wheels, coordinator state (rosbag record)
//   paths.png    planned (±2σ) against executed paths per robot (`plot_script` on run.json)
// report.txt and result.json ("bag", "plot") say when the bag or the plot is missing, and why.
//
// The record starts with the run: `~ready` (std_srvs/Trigger) succeeds only once the bag
// recorder and this node are linked to every publisher the master lists for each recorded
// topic (each publisher's own getBusInfo says so, checked 5 times a second) and a
// /ddace/entities message published after that has arrived (the second received since),
// so the bag holds the table at the start; the coordinator, given this node as
// roles/recorder, starts a new run only then. It is a role of the run, too: its link on
// /coordinator/state and its ~heartbeat (Heartbeat, ~heartbeat_rate_hz), which reports
// "rosbag record exited" when the recorder dies, are watched, and losing either stops the
// robots and aborts the run (a run without its record does not go on). The recorder gets
// SIGINT from the kernel when this node dies, so its bag is closed even then.
//
// Also checks the coordinator's contract on the wire: a DecisionRequest while any
// segment is still running (sent, not yet done/failed/aborted) is a violation.
//
//   in  /coordinator/state, /ddace/decision_request, /ddace/entities, /robots/E/segment,
//       /robots/E/segment_status
//   out ~heartbeat (Heartbeat)
//   srv  ~ready (std_srvs/Trigger)
//   params  task (absolute task directory), ground_truth_demo (index into demos/, -1 = none),
//           run_dir / runs_dir (above), record_bag (true), plot_script (absolute path, "" = no
//           plot; default: plot_run.py next to this executable, where the build installs it),
//           end_launch (true: SIGINT the parent roslaunch after the record is written),
//           timeout_s (give up; 0 = never)
#pragma once

#include <memory>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The execution_monitor node (src/nodes/execution_monitor_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses. The destructor writes the record
/// of a run that has not ended (interrupted).
class ExecutionMonitorNode {
 public:
  /// The node's own parameters (private namespace) with a fixed default, as
  /// config/execution.yaml (section execution_monitor) documents them. run_dir, runs_dir
  /// and plot_script default to places found at run time (above).
  struct Params {
    int ground_truth_demo = -1;  ///< index into the task's demos/ scored against; -1 = none
    bool record_bag = true;      ///< record run.bag (rosbag record)
    bool end_launch = true;      ///< SIGINT the parent roslaunch once the record is written
    double timeout_s = 0.0;      ///< give up and write the record after this long; 0 = never
    /// Two bodies overlapping deeper than this collide, metres: two touching bodies'
    /// measured gap carries both poses' noise (1 mm per axis each: 3.5 sigma).
    double collision_overlap_m = 0.005;
    /// A run with a collision is no success (OSR 0). True on real robots, where bodies
    /// are real; execute_sim.launch sets it to whether the simulated table has bodies
    /// (bodies:=true): on the points table (the paper's model, which ends a motion toward a
    /// robot at its centre) overlaps are counted and reported, not judged.
    bool collisions_fail = true;
  };

  ExecutionMonitorNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~ExecutionMonitorNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
