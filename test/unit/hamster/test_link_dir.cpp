// The claim of one run on its directory of mock Hamster links: a second live run is refused,
// a crashed run's claim is not, and only what a claim created is removed.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "ddace/common/error.h"
#include "ddace/hamster/link_dir.h"

using ddace::hamster::LinkDirClaim;
namespace fs = std::filesystem;

namespace {

const std::string kParameter = "parameter ~link_dir";

class LinkDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "ddace_link_dir_XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    root_ = tmpl;
  }
  void TearDown() override { fs::remove_all(root_); }

  /// The message of the error claiming `dir` throws, "" when the claim succeeds.
  static std::string refusal(const std::string& dir, const std::vector<std::string>& links = {"hamster_R1"}) {
    try {
      LinkDirClaim claim(dir, links, kParameter);
    } catch (const ddace::Error& e) {
      return e.what();
    }
    return "";
  }

  fs::path root_;
};

TEST_F(LinkDirTest, SecondLiveRunIsRefusedNamingDirParameterAndHolder) {
  const std::string dir = (root_ / "links").string();
  auto first = std::make_unique<LinkDirClaim>(dir, std::vector<std::string>{"hamster_R1"}, kParameter);
  const std::string why = refusal(dir);
  EXPECT_NE(why.find(dir), std::string::npos) << why;
  EXPECT_NE(why.find(kParameter), std::string::npos) << why;
  EXPECT_NE(why.find("in use by a live run (process " + std::to_string(::getpid())), std::string::npos) << why;
  // The refused claim removed nothing of the first one's.
  EXPECT_TRUE(fs::exists(fs::path(dir) / LinkDirClaim::lockFileName()));
  first.reset();
  EXPECT_FALSE(fs::exists(dir)) << "the directory the claim created is removed";
  EXPECT_EQ(refusal(dir), "") << "released, the directory is free again";
}

TEST_F(LinkDirTest, ClaimOfAnotherProcessIsRefusedUntilItDies) {
  const std::string dir = (root_ / "links").string();
  int ready[2], quit[2];
  ASSERT_EQ(::pipe(ready), 0);
  ASSERT_EQ(::pipe(quit), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // A run that holds the directory and then crashes (_exit: no destructor cleans up).
    LinkDirClaim claim(dir, {"hamster_R1"}, kParameter);
    char c = 1;
    if (::write(ready[1], &c, 1) != 1) ::_exit(2);
    if (::read(quit[0], &c, 1) < 0) ::_exit(2);
    ::_exit(0);
  }
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  const std::string why = refusal(dir);
  EXPECT_NE(why.find("in use by a live run (process " + std::to_string(child)), std::string::npos) << why;
  ASSERT_EQ(::write(quit[1], &c, 1), 1);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  // Its lock file is left behind, but no live process holds it: the next run may claim.
  EXPECT_TRUE(fs::exists(fs::path(dir) / LinkDirClaim::lockFileName()));
  EXPECT_EQ(refusal(dir), "");
  for (int fd : {ready[0], ready[1], quit[0], quit[1]}) ::close(fd);
}

TEST_F(LinkDirTest, ExistingLinkIsRefusedAndKeptAndAUsersDirectoryIsKept) {
  const fs::path dir = root_ / "mine";
  fs::create_directory(dir);
  std::ofstream(dir / "notes.txt") << "a user's file\n";
  fs::create_symlink("/dev/pts/999", dir / "hamster_R2");  // a crashed run's link
  const std::string why = refusal(dir.string(), {"hamster_R1", "hamster_R2"});
  EXPECT_NE(why.find("already holds hamster_R2"), std::string::npos) << why;
  EXPECT_EQ(why.find("hamster_R1"), std::string::npos) << why;
  EXPECT_TRUE(fs::is_symlink(dir / "hamster_R2"));
  fs::remove(dir / "hamster_R2");
  EXPECT_EQ(refusal(dir.string(), {"hamster_R1", "hamster_R2"}), "");
  // A directory the claim did not create stays, with the user's file, without the lock file.
  EXPECT_TRUE(fs::exists(dir / "notes.txt"));
  EXPECT_FALSE(fs::exists(dir / LinkDirClaim::lockFileName()));
}

TEST_F(LinkDirTest, MissingParentNamesTheParameter) {
  const std::string dir = (root_ / "no" / "such").string();
  const std::string why = refusal(dir);
  EXPECT_NE(why.find("cannot create " + kParameter + " " + dir), std::string::npos) << why;
}

}  // namespace
