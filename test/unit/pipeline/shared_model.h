// The fixture of a suite whose tests share one model: trained once, before the suite's
// first test, into a temporary directory, and removed after its last.
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "ddace/pipeline/evaluation.h"

namespace ddace::test {

/// `Training::kDir` names the model's directory (under the test's temporary directory);
/// `Training::train(dir)` trains the model there and returns it.
template <typename Training>
class SharedModel : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = ::testing::TempDir() + "/" + Training::kDir;
    std::filesystem::remove_all(dir_);
    model_ = std::make_unique<pipeline::Model>(Training::train(dir_));
  }
  static void TearDownTestSuite() {
    model_.reset();
    std::filesystem::remove_all(dir_);
  }
  static inline std::string dir_;
  static inline std::unique_ptr<pipeline::Model> model_;
};

}  // namespace ddace::test
