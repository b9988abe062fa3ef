// A role's node (here the path follower, whose task does not exist) exits before the run
// starts. The coordinator cannot see a link drop that never stood; roslaunch knows the
// process ended. The coordinator must abort the run that can never start, naming that node
// as exited (and the nodes never started only as awaited), and /coordinator/start must say
// so instead of "waiting for".
#include "exec_common.h"

TEST(EndedBeforeStart, TheCoordinatorNamesTheNodeThatExitedAndAborts) {
  ros::NodeHandle nh;
  std::mutex mu;
  ddace::CoordinatorState last;
  ros::Subscriber sub =
      nh.subscribe<ddace::CoordinatorState>("/coordinator/state", 5, [&](const ddace::CoordinatorState::ConstPtr& m) {
        const std::lock_guard<std::mutex> l(mu);
        last = *m;
      });
  ASSERT_TRUE(exec_test::waitFor(
      mu, [&] { return last.state == ddace::CoordinatorState::ABORTED; }, 40.0))
      << "the coordinator did not abort; its state: " << last.state_name << " " << last.reason;
  std::string reason;
  {
    const std::lock_guard<std::mutex> l(mu);
    reason = last.reason;
  }
  EXPECT_NE(reason.find("node /path_follower is not running: it exited before the run started"), std::string::npos)
      << reason;
  EXPECT_NE(reason.find("path_follower-"), std::string::npos) << "roslaunch's process name: " << reason;
  EXPECT_EQ(reason.find("node /sequence is not running"), std::string::npos) << "never started, not ended: " << reason;
  EXPECT_NE(reason.find("sequence node (node /sequence"), std::string::npos) << "still awaited: " << reason;

  std_srvs::Trigger t;
  ASSERT_TRUE(ros::service::call("/coordinator/start", t));
  EXPECT_FALSE(t.response.success);
  EXPECT_NE(t.response.message.find("node /path_follower is not running"), std::string::npos) << t.response.message;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_ended_before_start_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
