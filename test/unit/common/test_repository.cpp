// Finding the ddace package directory: explicit option > DDACE_REPO > walking up > ROS_PACKAGE_PATH.
#include "ddace/common/repository.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "ddace/common/error.h"

namespace fs = std::filesystem;
using ddace::locateRepository;
using ddace::RepositorySearch;

namespace {

const char* kManifest =
    "<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <!-- <name>other</name> -->\n  <name> ddace </name>\n"
    "  <version>0.1.0</version>\n</package>\n";

class RepositoryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "ddace_repo_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    root_ = fs::canonical(pattern);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  // A package directory `rel` with the given manifest and (relative) entries.
  fs::path package(const std::string& rel, const std::vector<std::string>& entries = {},
                   const std::string& manifest = kManifest) {
    const fs::path dir = root_ / rel;
    fs::create_directories(dir);
    std::ofstream(dir / "package.xml") << manifest;
    for (const auto& e : entries) fs::create_directories(dir / e);
    return dir;
  }
  std::string errorOf(const RepositorySearch& s) {
    try {
      locateRepository(s);
    } catch (const ddace::Error& e) {
      return e.what();
    }
    return "";
  }
  fs::path root_;
};

TEST_F(RepositoryTest, TheExplicitDirectoryComesFirstThenTheEnvironmentVariable) {
  const fs::path a = package("a"), b = package("b"), c = package("c");
  RepositorySearch s;
  s.explicit_dir = a.string();
  s.env_dir = b.string();
  s.walk_from = {c.string()};
  EXPECT_EQ(locateRepository(s), a);
  s.explicit_dir.clear();
  EXPECT_EQ(locateRepository(s), b);
  s.env_dir.clear();
  EXPECT_EQ(locateRepository(s), c);
}

TEST_F(RepositoryTest, AnExplicitDirectoryThatIsNotTheRepositoryIsAnErrorNotReplacedByAnother) {
  package("found");
  fs::create_directories(root_ / "empty");
  RepositorySearch s;
  s.walk_from = {(root_ / "found").string()};
  s.explicit_dir = (root_ / "empty").string();
  EXPECT_NE(errorOf(s).find("--repo " + (root_ / "empty").string() + ": not the ddace package directory"),
            std::string::npos)
      << errorOf(s);
  s.explicit_dir.clear();
  s.env_dir = (root_ / "empty").string();
  EXPECT_NE(errorOf(s).find("DDACE_REPO=" + (root_ / "empty").string()), std::string::npos) << errorOf(s);
  // ... also when it is the package but lacks what the caller needs.
  s.env_dir = package("nodocs").string();
  s.needs = {"docs/bench"};
  EXPECT_NE(errorOf(s).find("has no docs/bench"), std::string::npos) << errorOf(s);
}

TEST_F(RepositoryTest, WalksUpFromANestedDirectory) {
  const fs::path repo = package("repo");
  fs::create_directories(repo / "catkin_ws" / "devel" / "lib" / "ddace");
  RepositorySearch s;
  s.walk_from = {(repo / "catkin_ws" / "devel" / "lib" / "ddace").string()};
  EXPECT_EQ(locateRepository(s), repo);
}

TEST_F(RepositoryTest, AnotherPackageOrANameOnlyInACommentIsNotTheRepository) {
  const fs::path other = package("other", {}, "<package><name>ddace_extras</name></package>");
  const fs::path commented = package("commented", {}, "<package><!-- <name>ddace</name> --><name>x</name></package>");
  EXPECT_FALSE(ddace::isDdacePackage(other));
  EXPECT_FALSE(ddace::isDdacePackage(commented));
  EXPECT_TRUE(ddace::isDdacePackage(package("real")));
  EXPECT_FALSE(ddace::isDdacePackage(root_ / "nowhere"));
}

TEST_F(RepositoryTest, AFoundPackageWithoutWhatTheCallerNeedsIsSkipped) {
  // An install space's share/ddace has config/ but no docs/: a tool writing docs/ goes on
  // to the repository further up.
  const fs::path outer = package("outer", {"docs/bench", "config"});
  const fs::path inner = package("outer/install/share/ddace", {"config"});
  RepositorySearch s;
  s.walk_from = {inner.string()};
  s.needs = {"config"};
  EXPECT_EQ(locateRepository(s), inner);
  s.needs = {"docs/bench"};
  EXPECT_EQ(locateRepository(s), outer);
}

TEST_F(RepositoryTest, FindsTheInstallSpaceShareDirectoryFromItsExecutables) {
  const fs::path share = package("install/share/ddace", {"config"});
  fs::create_directories(root_ / "install" / "lib" / "ddace");
  RepositorySearch s;
  s.walk_from = {(root_ / "install" / "lib" / "ddace").string()};
  EXPECT_EQ(locateRepository(s), share);
}

TEST_F(RepositoryTest, APackageXmlReachedThroughASymlinkResolvesToTheRepository) {
  const fs::path repo = package("repo", {"docs"});
  const fs::path farm = root_ / "ws" / "src" / "ddace";
  fs::create_directories(farm);
  fs::create_symlink(repo / "package.xml", farm / "package.xml");
  RepositorySearch s;
  s.explicit_dir = farm.string();
  EXPECT_EQ(locateRepository(s), repo);
}

TEST_F(RepositoryTest, SearchesRosPackagePathLast) {
  package("ws/src/tools/not_ddace", {}, "<package><name>not_ddace</name></package>");
  const fs::path repo = package("ws/src/stack/ddace");
  fs::create_directories(root_ / "elsewhere");
  RepositorySearch s;
  s.walk_from = {(root_ / "elsewhere").string()};
  s.ros_package_path = (root_ / "nothing").string() + ":" + (root_ / "ws" / "src").string();
  EXPECT_EQ(locateRepository(s), repo);
}

TEST_F(RepositoryTest, NothingFoundSaysWhereItLookedAndHowToPointAtIt) {
  fs::create_directories(root_ / "elsewhere");
  package("elsewhere/share/ddace");  // an install space without test data
  RepositorySearch s;
  s.walk_from = {(root_ / "elsewhere").string()};
  s.needs = {"test/data"};
  const std::string e = errorOf(s);
  EXPECT_NE(e.find("cannot find the ddace package directory with test/data"), std::string::npos) << e;
  EXPECT_NE(e.find((root_ / "elsewhere").string() + " and its parents"), std::string::npos) << e;
  EXPECT_NE(e.find("$ROS_PACKAGE_PATH (unset)"), std::string::npos) << e;
  EXPECT_NE(e.find("skipped " + (root_ / "elsewhere/share/ddace").string() + " (no test/data)"), std::string::npos)
      << e;
  EXPECT_NE(e.find("Pass --repo DIR or set DDACE_REPO=DIR"), std::string::npos) << e;
}

TEST(FindRepository, TheTestsFindTheirOwnSourceTreeAtRunTime) {
  // How every test reads test/data and config/: no path compiled into the binary.
  const fs::path repo = ddace::findRepository("", {"test/unit/common/test_repository.cpp"});
  EXPECT_TRUE(ddace::isDdacePackage(repo));
  EXPECT_TRUE(fs::exists(repo / "test" / "data"));
}

}  // namespace
