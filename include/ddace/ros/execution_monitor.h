// execution_monitor_node: watches a run and, when it ends, prints the executed step
// sequence next to the ground truth and the trial's metrics (SSR, GCR, goal conditions,
// OSR; docs/task-format.md), then exits (launch files mark it required, so the
// graph shuts down with it).
//
// Also checks the coordinator's contract on the wire: a DecisionRequest while any
// segment is still running (sent, not yet done/failed/aborted) is a violation.
//
//   in  /coordinator/state, /ddace/decision_request, /robots/E/segment, /robots/E/segment_status
//   params  task (task directory), ground_truth_demo (index into demos/, -1 = none),
//           result_file (optional: the metrics as JSON), report_file (optional: the printed
//           report), timeout_s (give up; 0 = never)
#pragma once

#include <memory>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The execution_monitor node (src/nodes/execution_monitor_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class ExecutionMonitorNode {
 public:
  ExecutionMonitorNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~ExecutionMonitorNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
