// SequenceModel's state and its data preparation (internal to the tgn module).
#pragma once

#include <torch/torch.h>

#include <memory>
#include <string>
#include <vector>

#include "batching.h"
#include "ddace/tgn/sequence_model.h"
#include "network.h"

namespace ddace::tgn {

struct SequenceModel::Impl {
  task::TaskSpec spec;
  ModelInfo info;
  NetConfig cfg;
  Network net{nullptr};

  /// Index of `action` in the vocabulary, or -1.
  int vocabIndex(const std::string& action) const;
  /// The network of `info` (shapes, attention edges), weights initialised by libtorch.
  void build();
  /// build() with the weights initialised from the model's seed.
  void seededBuild();
  /// Normalised node features of one row / snapshot into out[N][features].
  void features(const std::vector<Eigen::Vector2d>& pos, const std::vector<task::Label>* labels, float* out) const;
  Sequence keyframeSequence(const task::Demonstration& d) const;
  Sequence frameSequence(const task::Demonstration& d) const;
  /// Every demonstration as a Sequence (keyframes, or frames for gnn); throws ddace::Error
  /// naming the demonstration when it does not fit the model.
  std::vector<Sequence> sequences(const std::vector<task::Demonstration>& demos) const;
  /// Exact-step (gnn: frame label) accuracy, eval mode.
  double accuracy(const std::vector<Sequence>& seqs);
};

/// Spec, vocabulary, E', attention edges and normalisation: everything but the weights.
std::shared_ptr<SequenceModel::Impl> prepare(const task::TaskDir& train, const TrainOptions& options);

}  // namespace ddace::tgn
