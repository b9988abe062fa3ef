// writeOwnedDirectory with content written by other code (how `ddace train` writes a
// model): a failed fill leaves the old output, a directory that changed while the fill
// ran is checked again, errors name the final place, never the temporary one; and the
// ownership record it keeps (SHA-256; an older FNV-1a 64 record still read).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/sha256.h"
#include "ddace/task/owned_dir.h"
#include "../common/file_tree.h"

using namespace ddace;
using ddace::test::fileBytes;
using ddace::test::fileTree;
namespace fs = std::filesystem;

namespace {

/// DIR/out in a parent of its own (the tests count what is beside it).
std::string fresh(const std::string& name) {
  const std::string parent = ::testing::TempDir() + "/ddace_owned_fill_" + std::to_string(::getpid()) + "/" + name;
  fs::remove_all(parent);
  fs::create_directories(parent);
  return parent + "/out";
}

size_t siblings(const std::string& dir) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(fs::path(dir).parent_path())) n += e.path().string() != dir;
  return n;
}

void writeModel(const std::string& dir, const std::string& weights) {
  fs::create_directories(dir + "/sub");
  writeTextFile(dir + "/weights.pt", weights);
  writeTextFile(dir + "/sub/loss.csv", "epoch,loss\n1,0.5\n");
}

}  // namespace

TEST(OwnedFill, WritesAndReplacesItsOwnOutputWhole) {
  const std::string dir = fresh("whole");
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeModel(tmp, "old"); }, "ddace train", false);
  writeTextFile(dir + "/../keep.txt", "not in the directory");
  ASSERT_EQ(fileBytes(dir + "/weights.pt"), "old");
  ASSERT_TRUE(fs::exists(dir + "/" + task::kOwnedManifest));
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeTextFile(tmp + "/weights.pt", "new"); }, "ddace train", true);
  EXPECT_EQ(fileBytes(dir + "/weights.pt"), "new");
  EXPECT_FALSE(fs::exists(dir + "/sub"));  // nothing of the old output survives
  EXPECT_EQ(siblings(dir), 1u);            // keep.txt only: no temporary left
}

TEST(OwnedFill, AFailingFillLeavesTheOldOutputAndNoTemporary) {
  const std::string dir = fresh("failing");
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeModel(tmp, "old"); }, "ddace train", false);
  const auto before = fileTree(dir);
  std::string seen_tmp;
  try {
    task::writeOwnedDirectory(
        dir,
        [&](const std::string& tmp) {
          seen_tmp = tmp;
          writeTextFile(tmp + "/weights.pt", "half");
          throw Error(Diagnostic{tmp + "/weights.pt", 0, 0, "cannot write the weights to " + tmp});
        },
        "ddace train", true);
    FAIL();
  } catch (const Error& e) {
    ASSERT_EQ(e.diagnostics().size(), 1u);
    EXPECT_EQ(e.diagnostics()[0].file, dir + "/weights.pt");
    EXPECT_EQ(e.diagnostics()[0].message, "cannot write the weights to " + dir);
  }
  EXPECT_NE(seen_tmp, dir);
  EXPECT_EQ(fileTree(dir), before);
  EXPECT_FALSE(fs::exists(seen_tmp));
  EXPECT_EQ(siblings(dir), 0u);
}

TEST(OwnedFill, AFileAddedWhileTheFillRanIsNotReplaced) {
  const std::string dir = fresh("raced");
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeModel(tmp, "old"); }, "ddace train", false);
  try {
    task::writeOwnedDirectory(
        dir,
        [&](const std::string& tmp) {
          writeModel(tmp, "new");
          writeTextFile(dir + "/eval.json", "{}");  // the user, meanwhile
        },
        "ddace train", true);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir + "/eval.json (not written by ddace train)"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(fileBytes(dir + "/weights.pt"), "old");
  EXPECT_EQ(fileBytes(dir + "/eval.json"), "{}");
  EXPECT_EQ(siblings(dir), 0u);
}

TEST(OwnedFill, AnotherToolsOutputIsNotItsOwn) {
  const std::string dir = fresh("other_tool");
  task::writeOwnedDirectory(dir, {{"train/task.yaml", "x: 1\n"}}, "ddace generate", false);
  try {
    task::writeOwnedDirectory(
        dir, [](const std::string& tmp) { writeModel(tmp, "w"); }, "ddace train", true);
    FAIL();
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(dir + "/train/task.yaml (written by ddace generate, not ddace train)"), std::string::npos)
        << what;
    EXPECT_NE(what.find(dir + "/" + task::kOwnedManifest + " (the manifest of ddace generate's output)"),
              std::string::npos)
        << what;
  }
  EXPECT_EQ(fileBytes(dir + "/train/task.yaml"), "x: 1\n");
}

TEST(OwnedRecord, ListsEveryFileWithItsSha256AndSize) {
  const std::string dir = fresh("record");
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeModel(tmp, "new"); }, "ddace train", false);
  // As the header of owned_dir.h documents it: sorted by path, SHA-256, bytes, path.
  EXPECT_EQ(fileBytes(dir + "/" + task::kOwnedManifest),
            "# ddace train wrote these files (SHA-256, bytes, path); it replaces only these\n" +
                sha256Hex("epoch,loss\n1,0.5\n") + " 17 sub/loss.csv\n" + sha256Hex("new") + " 3 weights.pt\n");
}

// An output written before the record switched to SHA-256 (FNV-1a 64 digests, worked
// out independently of the code under test) is still the tool's own.
namespace {
const std::string kOldRecord =
    "# ddace train wrote these files (FNV-1a 64, bytes, path); it replaces only these\n"
    "9ffd3109c420c9b9 17 sub/loss.csv\n"
    "1a0fad1921d08076 3 weights.pt\n";
}  // namespace

TEST(OwnedRecord, AnOldFnvRecordIsStillTheToolsOwnAndIsRewrittenWithSha256) {
  const std::string dir = fresh("old_record");
  writeModel(dir, "old");
  writeTextFile(dir + "/" + task::kOwnedManifest, kOldRecord);
  const auto before = fileTree(dir);
  // Without --force: refused as an earlier output of the tool, not as somebody else's.
  try {
    task::writeOwnedDirectory(
        dir, [](const std::string& tmp) { writeModel(tmp, "new"); }, "ddace train", false);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("holds the output of an earlier ddace train; --force replaces it"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(fileTree(dir), before);
  task::writeOwnedDirectory(
      dir, [](const std::string& tmp) { writeTextFile(tmp + "/weights.pt", "new"); }, "ddace train", true);
  EXPECT_EQ(fileBytes(dir + "/weights.pt"), "new");
  EXPECT_FALSE(fs::exists(dir + "/sub"));
  EXPECT_EQ(fileBytes(dir + "/" + task::kOwnedManifest),
            "# ddace train wrote these files (SHA-256, bytes, path); it replaces only these\n" + sha256Hex("new") +
                " 3 weights.pt\n");
}

TEST(OwnedRecord, AFileEditedSinceAnOldFnvRecordIsNotReplaced) {
  const std::string dir = fresh("old_record_edited");
  writeModel(dir, "old");
  writeTextFile(dir + "/" + task::kOwnedManifest, kOldRecord);
  writeTextFile(dir + "/weights.pt", "odd");  // the same size, other bytes
  const auto before = fileTree(dir);
  try {
    task::writeOwnedDirectory(
        dir, [](const std::string& tmp) { writeModel(tmp, "new"); }, "ddace train", true);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir + "/weights.pt (changed since ddace train wrote it)"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(fileTree(dir), before);
}

TEST(OwnedRecord, ARecordOfAnUnknownHashIsNotOneTheToolCanRead) {
  const std::string dir = fresh("unknown_hash");
  writeModel(dir, "old");
  std::string record = kOldRecord;
  record.replace(record.find("FNV-1a 64"), 9, "MD5");
  writeTextFile(dir + "/" + task::kOwnedManifest, record);
  try {
    task::writeOwnedDirectory(
        dir, [](const std::string& tmp) { writeModel(tmp, "new"); }, "ddace train", true);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(not a manifest ddace train can read)"), std::string::npos) << e.what();
  }
  EXPECT_EQ(fileBytes(dir + "/weights.pt"), "old");
}
