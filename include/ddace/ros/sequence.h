// sequence_node: answers the coordinator's decision requests with the next step or END.
//
//   in  /ddace/decision_request (DecisionRequest: the snapshot history)
//   out /ddace/decision (Decision), ~heartbeat (Heartbeat, ~heartbeat_rate_hz: the
//       coordinator's role watch notices a hung node by its silence)
//
// Policy sources (parameter `policy`):
//   model   the temporal graph network of a model directory (`model`, written by
//           `ddace train`): tgn::SequenceModel::predictNext on the snapshot history.
//           Loaded through pipeline::loadModel (every file verified); a model of another
//           task than `task` (task fingerprint: entities, kinds, vocabulary, goal
//           conditions, step structure when `task` has demos/) is refused unless
//           `allow_other_task` is true.
//   replay  the step sequence of one demonstration (`replay_csv`, or `task`'s demos/ by
//           `replay_demo` index), open loop: step k for the k-th request, then END.
// Parameters: config/execution.yaml, section sequence.
#pragma once

#include <memory>
#include <string>

#include <ros/node_handle.h>

namespace ddace::nodes {

/// The sequence node (src/nodes/sequence_node.cpp runs it). The constructor reads the
/// private parameters from `pnh`, advertises and subscribes on `nh`, and throws
/// ddace::Error naming the parameter or file it refuses.
class SequenceNode {
 public:
  /// Where the next step comes from (parameter `policy`: "model" or "replay").
  enum class Policy { Model, Replay };
  /// "model" / "replay"; throws ddace::Error naming `param_name` otherwise.
  static Policy parsePolicy(const std::string& value, const std::string& param_name);

  /// The node's own parameters and their defaults (config/execution.yaml, section sequence).
  struct Params {
    Policy policy = Policy::Replay;
    int replay_demo = 0;            ///< which demonstration of the task's demos/ to replay
    bool allow_other_task = false;  ///< policy model: accept a model of another task (deliberate
                                    ///< transfer) instead of refusing it (task::requireSameTask)
  };

  SequenceNode(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~SequenceNode();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ddace::nodes
