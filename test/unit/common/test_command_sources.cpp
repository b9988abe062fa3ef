#include "ddace/common/command_sources.h"

#include <gtest/gtest.h>

#include "ddace/common/error.h"

using ddace::CommandSources;
using Verdict = CommandSources::Verdict;

TEST(CommandSources, OnlyTheNamedNodesCommandAndEveryRefusalIsCountedAndNamed) {
  CommandSources s({"/path_follower", "/coordinator"}, "parameter '~command_sources'");
  EXPECT_EQ(s.check("/path_follower", true), Verdict::Accepted);
  EXPECT_EQ(s.check("/coordinator", true), Verdict::Accepted);
  for (int i = 0; i < 40; ++i) EXPECT_EQ(s.check("/intruder", true), Verdict::Foreign);
  // A prefix or a relative spelling of an allowed name is another node.
  EXPECT_EQ(s.check("/path_follower_2", true), Verdict::Foreign);
  EXPECT_EQ(s.check("/path_follower/x", true), Verdict::Foreign);
  EXPECT_EQ(s.check("/intruder", true), Verdict::Foreign);
  EXPECT_EQ(s.foreign(), 43u);
  EXPECT_EQ(s.foreignReport(), "43, last from /intruder");
  EXPECT_EQ(s.unstamped(), 0u);
  EXPECT_EQ(s.unstampedReport(), "0");
}

TEST(CommandSources, AnUnstampedCommandIsRefusedEvenFromAnAllowedNode) {
  CommandSources s({"/path_follower"}, "p");
  EXPECT_EQ(s.check("/path_follower", false), Verdict::Unstamped);
  EXPECT_EQ(s.unstampedReport(), "1, last from /path_follower");
  // Foreign first: an unstamped command of a stranger counts as foreign.
  EXPECT_EQ(s.check("/intruder", false), Verdict::Foreign);
  EXPECT_EQ(s.unstamped(), 1u);
  EXPECT_EQ(s.foreign(), 1u);
}

TEST(CommandSources, AnEmptyListOrARelativeNameIsAnErrorNamingTheParameter) {
  auto message = [](std::vector<std::string> names) {
    try {
      CommandSources(std::move(names), "parameter '/hamster_bridge/command_sources'");
    } catch (const ddace::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({}).find("'/hamster_bridge/command_sources' is empty"), std::string::npos) << message({});
  EXPECT_NE(message({"path_follower"}).find("'path_follower', not an absolute node name"), std::string::npos);
  EXPECT_NE(message({"/"}).find("not an absolute node name"), std::string::npos);
  EXPECT_EQ(message({"/path_follower", "/coordinator"}), "no error");
}
