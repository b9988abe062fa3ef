// Training and loading a model leave the process's torch state alone: the global random
// generator (neither reseeded nor advanced) and the intra-op thread count.
#include <gtest/gtest.h>
#include <torch/torch.h>

#include <filesystem>

#include "ddace/tasks/generators.h"
#include "ddace/tgn/sequence_model.h"

using namespace ddace;
namespace fs = std::filesystem;

TEST(SequenceModel, TrainingAndLoadingLeaveTorchsGeneratorAndThreadCountAlone) {
  tasks::GeneratorOptions g;
  g.family = "task4";
  g.demos = 2;
  const task::TaskDir train = tasks::generate(g);
  tgn::TrainOptions o;
  o.max_epochs = 2;
  o.threads = 2;
  const fs::path dir = fs::temp_directory_path() / ("ddace_test_tgn_state_" + std::to_string(::getpid()));
  fs::remove_all(dir);

  at::set_num_threads(1);
  torch::manual_seed(123);
  const torch::Tensor expected = torch::rand({8});

  torch::manual_seed(123);
  const auto model = tgn::SequenceModel::train(train, o, nullptr);
  EXPECT_TRUE(torch::equal(torch::rand({8}), expected)) << "training drew from or reseeded the global generator";
  EXPECT_EQ(at::get_num_threads(), 1) << "training left its thread count behind";
  model.save(dir.string());

  torch::manual_seed(123);
  const auto loaded = tgn::SequenceModel::load(dir.string());
  EXPECT_TRUE(torch::equal(torch::rand({8}), expected)) << "loading drew from or reseeded the global generator";
  EXPECT_EQ(at::get_num_threads(), 1) << "loading set the thread count";
  // And the model is the same: the seeded initialisation did not depend on the global state.
  torch::manual_seed(999);
  const auto again = tgn::SequenceModel::train(train, o, nullptr);
  EXPECT_EQ(again.info().history.back().loss, model.info().history.back().loss);
  fs::remove_all(dir);
}
