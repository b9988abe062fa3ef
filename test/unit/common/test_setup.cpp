// scripts/setup's "nothing to build": every command that sets up first (scripts/execute_sim,
// scripts/run, scripts/test) skips the build when no file of the repository changed since
// the last complete build began, and builds again when one did: changed, added or removed.
// What git ignores (out/, __pycache__) and the workspace itself change nothing.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../common/run_tool.h"
#include "ddace/common/repository.h"

namespace fs = std::filesystem;

namespace {

/// A repository with scripts/setup and a few sources, built: its workspace holds the tool and
/// the stamp of a complete build, every source older than that stamp.
class SetupCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "ddace_setup_check_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    repo_ = fs::canonical(pattern);
    const fs::path setup = ddace::findRepository("", {"scripts/setup"}) / "scripts" / "setup";
    fs::create_directories(repo_ / "scripts");
    fs::copy_file(setup, repo_ / "scripts" / "setup");
    for (const char* f : {"src/cli/main.cpp", "include/ddace/a.h", "CMakeLists.txt", "catkin_ws/devel/setup.bash",
                          "catkin_ws/devel/lib/ddace/ddace", "catkin_ws/build/ddace_built"})
      write(f);
    fs::permissions(repo_ / "catkin_ws/devel/lib/ddace/ddace", fs::perms::owner_all);
    // The build began after every source was written (and after any Debian package changed).
    ASSERT_EQ(sh("find . -exec touch -h -d @" + std::to_string(now() - 100) + " {} +"), 0);
    stampAt(now() + 1000);
  }
  void TearDown() override { fs::remove_all(repo_); }

  static long now() { return static_cast<long>(::time(nullptr)); }
  void write(const std::string& rel) {
    fs::create_directories((repo_ / rel).parent_path());
    std::ofstream(repo_ / rel) << "x\n";
  }
  void stampAt(long t) { ASSERT_EQ(sh("touch -d @" + std::to_string(t) + " catkin_ws/build/ddace_built"), 0); }
  /// Status of `command` run in the repository.
  int sh(const std::string& command) const {
    return ddace::test::runShell("cd '" + repo_.string() + "' && " + command).status;
  }
  /// 0: nothing to build; 1: a build is needed.
  int check() const { return sh("scripts/setup --check"); }
  /// A file's time after the stamp's (as an edit made after the build began).
  void touchLater(const std::string& rel) const {
    ASSERT_EQ(sh("touch -d @" + std::to_string(now() + 2000) + " '" + rel + "'"), 0);
  }

  fs::path repo_;
};

}  // namespace

TEST_F(SetupCheck, NothingChangedNeedsNoBuild) {
  EXPECT_EQ(check(), 0);
}

TEST_F(SetupCheck, AChangedSourceIsBuilt) {
  touchLater("src/cli/main.cpp");
  EXPECT_EQ(check(), 1);
}

TEST_F(SetupCheck, AnAddedOrRemovedFileIsBuilt) {
  fs::remove(repo_ / "include/ddace/a.h");
  touchLater("include/ddace");  // what removing it did to its directory
  EXPECT_EQ(check(), 1);
}

TEST_F(SetupCheck, ABuildThatNeverCompletedIsBuilt) {
  fs::remove(repo_ / "catkin_ws/build/ddace_built");
  EXPECT_EQ(check(), 1);
}

TEST_F(SetupCheck, AToolCleanedAwayIsBuilt) {
  fs::remove(repo_ / "catkin_ws/devel/lib/ddace/ddace");
  EXPECT_EQ(check(), 1);
}

TEST_F(SetupCheck, WhatGitIgnoresAndTheWorkspaceChangeNothing) {
  write("out/task4/task.yaml");
  write("scripts/__pycache__/plot_run.cpython-311.pyc");
  write("catkin_ws/build/CMakeCache.txt");
  touchLater("out/task4/task.yaml");
  touchLater("out");
  touchLater("scripts/__pycache__");
  touchLater("catkin_ws/build/CMakeCache.txt");
  // Their first creation also dates the directories holding them (one more build, once).
  ASSERT_EQ(sh("touch -d @" + std::to_string(now() - 100) + " . scripts"), 0);
  EXPECT_EQ(check(), 0);
}
