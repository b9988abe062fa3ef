// rostest: hamster_bridge_node configured with a wrong robot address. What the user
// sees: a console warning naming the address found on the port, the ports searched,
// and ERROR in the diagnostics while the robot is unreachable.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <rosgraph_msgs/Log.h>

#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace {

struct Seen {
  std::mutex mutex;
  std::vector<std::string> warnings;  // WARN lines of the bridge on /rosout
  int diag_level = -1;
  std::string diag_summary;
};

bool waitFor(const std::function<bool()>& done, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (done()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return done();
}

}  // namespace

TEST(HamsterWrongAddress, WarnsWithTheFoundAddressAndSaysErrorInTheDiagnostics) {
  Seen seen;
  ros::NodeHandle nh;
  auto log_sub = nh.subscribe<rosgraph_msgs::Log>("/rosout", 100, [&](const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->name != "/hamster_bridge" || m->level != rosgraph_msgs::Log::WARN) return;
    std::lock_guard<std::mutex> lock(seen.mutex);
    seen.warnings.push_back(m->msg);
  });
  auto diag_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        for (const auto& s : m->status) {
          if (s.name.find("hamster R1") == std::string::npos) continue;
          std::lock_guard<std::mutex> lock(seen.mutex);
          seen.diag_level = s.level;
          seen.diag_summary = s.message;
        }
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  auto has = [&](const std::string& text) {
    std::lock_guard<std::mutex> lock(seen.mutex);
    for (const auto& w : seen.warnings)
      if (w.find(text) != std::string::npos) return true;
    return false;
  };
  // The first report may pass before /rosout connects; it repeats every 10 s.
  EXPECT_TRUE(waitFor([&] { return has("carries robot B1:00:00:00:00:00, which is not in the config"); }, 25.0))
      << "no warning naming the address found on the port";
  // Said once the robot has been searched for search_quiet_s (3 s by default).
  EXPECT_TRUE(waitFor([&] { return has("robot A1:00:00:00:00:00 not found on 1 ports searched"); }, 15.0))
      << "no warning listing the ports searched";
  EXPECT_TRUE(waitFor(
      [&] {
        std::lock_guard<std::mutex> lock(seen.mutex);
        return seen.diag_level == diagnostic_msgs::DiagnosticStatus::ERROR;
      },
      5.0))
      << "diagnostics level " << seen.diag_level << ": " << seen.diag_summary;
  std::lock_guard<std::mutex> lock(seen.mutex);
  EXPECT_NE(seen.diag_summary.find("unreachable"), std::string::npos) << seen.diag_summary;
  // Not once per scan (a scan every 0.5 s): at most every 10 s.
  int foreign = 0;
  for (const auto& w : seen.warnings) foreign += w.find("which is not in the config") != std::string::npos;
  EXPECT_LE(foreign, 3);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hamster_wrong_address_test");
  ros::NodeHandle nh;  // keeps roscpp up for the whole test
  return RUN_ALL_TESTS();
}
