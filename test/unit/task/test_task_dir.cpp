// Task directories: every error of every file, partial recordings, nothing loaded on error.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <map>

#include "ddace/task/task_dir.h"

#include "../common/file_tree.h"
#include "../common/generated_task.h"

using namespace ddace;
using ddace::test::fileBytes;
using ddace::test::generated;
using ddace::test::writeBytes;
namespace fs = std::filesystem;

namespace {

std::string makeDir(const std::string& name) {
  const std::string path = ::testing::TempDir() + "/ddace_taskdir_" + name;
  fs::remove_all(path);
  task::writeTaskDir(generated("task4", 3, 1), path);
  return path;
}

}  // namespace

TEST(TaskDir, ReadsDemosInFileNameOrder) {
  const std::string path = makeDir("order");
  const task::TaskDir dir = task::loadTaskDir(path);
  ASSERT_EQ(dir.demos.size(), 3u);
  EXPECT_EQ(fs::path(dir.demos[0].source).filename(), "demo_000.csv");
  EXPECT_EQ(fs::path(dir.demos[2].source).filename(), "demo_002.csv");
  EXPECT_EQ(dir.vocabulary(), (std::vector<std::string>{"move"}));
}

TEST(TaskDir, OneBadFileMeansNothingIsLoadedAndEveryErrorIsListed) {
  const std::string path = makeDir("bad");
  writeBytes(path + "/demos/demo_001.csv", "t,R1.x\n0,1\n");
  writeBytes(path + "/demos/demo_002.csv", "");
  const task::TaskDirReport report = task::checkTaskDir(path);
  EXPECT_GE(report.errors.size(), 2u);
  EXPECT_EQ(report.dir.demos.size(), 1u);  // only the good one
  try {
    task::loadTaskDir(path);
    FAIL();
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("demo_001.csv:1:1: missing required column 'R1.y'"), std::string::npos) << what;
    EXPECT_NE(what.find("demo_002.csv:1:1: file is empty"), std::string::npos) << what;
  }
}

TEST(TaskDir, PartialRecordingsAreReported) {
  const std::string path = makeDir("partial");
  fs::copy_file(path + "/demos/demo_000.csv", path + "/demos/demo_003.csv.partial");
  const task::TaskDirReport report = task::checkTaskDir(path);
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_NE(report.errors[0].str().find("demo_003.csv.partial: partial recording"), std::string::npos);
}

TEST(TaskDir, MissingPiecesAreNamed) {
  EXPECT_NE(task::checkTaskDir("/nonexistent_ddace").errors.at(0).message.find("not a task directory"),
            std::string::npos);
  const std::string path = makeDir("missing");
  fs::remove_all(path + "/demos");
  EXPECT_NE(task::checkTaskDir(path).errors.at(0).message.find("no demonstrations"), std::string::npos);
  fs::remove(path + "/task.yaml");
  EXPECT_NE(task::checkTaskDir(path).errors.at(0).message.find("missing task.yaml"), std::string::npos);
}

TEST(TaskDir, RewritingRemovesOldDemonstrations) {
  const std::string path = makeDir("rewrite");
  task::writeTaskDir(generated("task4", 1, 1), path);
  EXPECT_EQ(task::loadTaskDir(path).demos.size(), 1u);
}

// ---- nothing a user owns is lost: the data-loss cases first

namespace {

/// Everything under `dir`, path -> bytes (directories as "<dir>/").
std::map<std::string, std::string> tree(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    out[fs::relative(e.path(), dir).string() + (e.is_directory() ? "/" : "")] =
        e.is_directory() ? "" : fileBytes(e.path());
  return out;
}

std::string freshDir(const std::string& name) {
  const std::string path = ::testing::TempDir() + "/ddace_owned_" + name;
  fs::remove_all(path);
  return path;
}

}  // namespace

TEST(OwnedOutput, AUsersRecordingAndHandWrittenTaskYamlAreNeverReplaced) {
  const std::string path = freshDir("user");
  fs::create_directories(path + "/demos");
  writeBytes(path + "/task.yaml", "format: ddace-task/1\n# my scene\nentities: [{name: R1, kind: robot}]\n");
  writeBytes(path + "/demos/my_recording.csv", "t,R1.x,R1.y\n0,0.1,0.1\n");
  const auto before = tree(path);
  try {
    task::writeTaskDir(generated("task4", 2, 1), path);
    FAIL();
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("my_recording.csv (not written by ddace)"), std::string::npos) << what;
    EXPECT_NE(what.find("task.yaml (not written by ddace)"), std::string::npos) << what;
  }
  EXPECT_EQ(tree(path), before);
  // Nothing was left next to it either.
  for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".ddace_owned_user.tmp"), std::string::npos) << e.path();
}

TEST(OwnedOutput, ItsOwnOutputIsReplacedWholeSoNoStaleDemonstrationSurvives) {
  const std::string path = freshDir("own");
  task::writeTaskDir(generated("task4", 5, 1), path);
  EXPECT_TRUE(fs::exists(path + "/" + task::kOwnedManifest));
  task::writeTaskDir(generated("task4", 2, 1), path);
  EXPECT_EQ(task::loadTaskDir(path).demos.size(), 2u);
  EXPECT_FALSE(fs::exists(path + "/demos/demo_004.csv"));
  // A file it wrote, then changed by hand, is no longer its own.
  writeBytes(path + "/demos/demo_001.csv", fileBytes(path + "/demos/demo_001.csv") + "\n");
  try {
    task::writeTaskDir(generated("task4", 2, 1), path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("demo_001.csv (changed since ddace wrote it)"), std::string::npos) << e.what();
  }
}

TEST(OwnedOutput, WithoutReplaceItsOwnEarlierOutputIsRefusedToo) {
  const std::string path = freshDir("noreplace");
  const auto files = task::taskDirFiles(generated("task4", 1, 1));
  task::writeOwnedDirectory(path, files, "ddace generate", false);
  try {
    task::writeOwnedDirectory(path, files, "ddace generate", false);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("earlier ddace generate; --force replaces it"), std::string::npos) << e.what();
  }
  // An empty directory is fine.
  const std::string empty = freshDir("empty");
  fs::create_directories(empty);
  task::writeOwnedDirectory(empty, files, "ddace generate", false);
  EXPECT_TRUE(fs::exists(empty + "/task.yaml"));
}

TEST(OwnedOutput, OutputWrittenBeforeManifestsExistedIsReplacedOnlyWhereIdentical) {
  const std::string path = freshDir("legacy");
  task::writeOwnedDirectory(path, task::taskDirFiles(generated("task4", 3, 1)), "ddace", true);
  fs::remove(path + "/" + task::kOwnedManifest);  // as an older ddace left it
  // demo_002.csv would not be rewritten, and without a manifest nothing says it is ours.
  try {
    task::writeOwnedDirectory(path, task::taskDirFiles(generated("task4", 2, 1)), "ddace", true);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("demo_002.csv (not written by ddace)"), std::string::npos) << e.what();
  }
  // Every file byte-identical to what replaces it: nothing can be lost.
  EXPECT_NO_THROW(task::writeOwnedDirectory(path, task::taskDirFiles(generated("task4", 3, 1)), "ddace", true));
}

TEST(OwnedOutput, AFailedWriteLeavesTheOldOutputIntactAndNoTemporaryBehind) {
  const std::string path = freshDir("failed");
  task::writeTaskDir(generated("task4", 3, 1), path);
  const auto before = tree(path);
  std::vector<task::OwnedFile> files = task::taskDirFiles(generated("task4", 2, 1));
  files.emplace_back("demos/" + std::string(300, 'x') + ".csv", "t\n");  // a name too long for the file system
  try {
    task::writeOwnedDirectory(path, files, "ddace", true);
    FAIL();
  } catch (const Error& e) {
    // The error names the file where it would have been.
    EXPECT_EQ(e.diagnostics().at(0).file.rfind(path + "/demos/xxx", 0), 0u) << e.what();
  }
  EXPECT_EQ(tree(path), before);
  for (const auto& e : fs::directory_iterator(fs::path(path).parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".ddace_owned_failed.tmp"), std::string::npos) << e.path();
  // Paths that leave the directory are refused before anything is written.
  EXPECT_THROW(task::writeOwnedDirectory(path, {{"../escape.csv", "x"}}, "ddace", true), Error);
  EXPECT_THROW(task::writeOwnedDirectory(path, {{"/abs.csv", "x"}}, "ddace", true), Error);
  EXPECT_EQ(tree(path), before);
}

TEST(OwnedOutput, NotADirectoryIsRefused) {
  const std::string path = freshDir("file");
  writeBytes(path, "mine");
  EXPECT_THROW(task::writeTaskDir(generated("task4", 1, 1), path), Error);
  EXPECT_EQ(fileBytes(path), "mine");
}

// ---- unreadable directories and special files are one error each, nothing hangs

TEST(TaskDir, ASymlinkLoopIsOneErrorAndAFifoTaskYamlDoesNotHang) {
  const std::string loop = freshDir("loop");
  fs::create_symlink(loop + "_b", loop);
  fs::create_symlink(loop, loop + "_b");
  auto errors = task::checkTaskDir(loop).errors;
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].str().find("symbolic links"), std::string::npos) << errors[0].str();
  fs::remove(loop);
  fs::remove(loop + "_b");

  const std::string dir = makeDir("fifo");
  fs::remove(dir + "/task.yaml");
  ASSERT_EQ(::mkfifo((dir + "/task.yaml").c_str(), 0600), 0);
  errors = task::checkTaskDir(dir).errors;
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].str().find("task.yaml: cannot read: is a FIFO"), std::string::npos) << errors[0].str();

  const std::string demos_loop = makeDir("demosloop");
  fs::remove_all(demos_loop + "/demos");
  fs::create_symlink(demos_loop + "/demos", demos_loop + "/demos");  // demos -> itself
  errors = task::checkTaskDir(demos_loop).errors;
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].str().find("demos: cannot read"), std::string::npos) << errors[0].str();
}

TEST(TaskDir, TheNthDemonstrationIsFoundOrTheErrorNamesDirectoryAndCount) {
  const std::string path = makeDir("nth");
  EXPECT_EQ(fs::path(task::demoFile(path, 2)).filename(), "demo_002.csv");
  EXPECT_EQ(task::demoFiles(path).size(), 3u);
  try {
    task::demoFile(path, 3, "parameter '/monitor/ground_truth_demo'");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "parameter '/monitor/ground_truth_demo' = 3, but " + path + "/demos has 3 demonstrations (0..2)");
  }
  EXPECT_THROW(task::demoFile(path, -1), Error);
  EXPECT_THROW(task::demoFile("/nonexistent_ddace", 0), Error);
}
