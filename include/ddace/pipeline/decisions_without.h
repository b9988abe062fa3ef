// A learned model deciding for the team without robots lost for good
// (exec::CoordinatorConfig::robot_lost_after_s, exec::DecisionRequest::lost): the model
// bound to the task without them (tgn::SequenceModel::boundTo, as `ddace eval` binds a
// model to a test set of fewer robots), deciding from the snapshots without their
// positions; its tokens name the task's entities again. The one answer of `ddace eval
// --perturb robot_lost` and of the sequence node.
//
// Owns: the reduced team and the binding; whether an END finishes the task (unfinishedEnd). Must not: decide who is
// lost (the coordinator).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "ddace/task/demonstration.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::pipeline {

class DecisionsWithout {
 public:
  /// `model`: the model on the task's own entities (its spec() is the task); kept by reference.
  explicit DecisionsWithout(const tgn::SequenceModel& model);
  /// The model's prediction from `history` (every entity of the task, oldest first) for the
  /// team without `lost` (task indices; empty: the model's own). Throws ddace::Error naming
  /// the lost entities when the model cannot be bound without them (a fixed order, a kind
  /// left empty) or an index lies outside the task, and with unfinishedEnd's reason for an
  /// END of the team without `lost` that does not finish the task.
  tgn::Prediction predict(const std::vector<task::Snapshot>& history, const std::vector<int>& lost);

 private:
  const tgn::SequenceModel& model_;
  std::unique_ptr<tgn::SequenceModel> bound_;  ///< bound to the team without `bound_lost_`
  std::vector<int> bound_lost_;
  std::vector<int> kept_;  ///< the reduced team's entities, by task index
};

/// Why the END of `p` does not finish the task, "" when it does (or `p` is no END): the scene
/// lacks what every demonstration's last scene had (tgn::Prediction::end_short), naming
/// `lost` (the lost robots, "" for none) as the reason the team cannot go on. The run
/// aborts with it (DecisionsWithout::predict throws it for a team with robots lost).
std::string unfinishedEnd(const tgn::Prediction& p, const std::string& lost);

}  // namespace ddace::pipeline
