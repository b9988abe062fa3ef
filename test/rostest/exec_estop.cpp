// E-stop on the whole graph: the ~estop service and the latched /ddace/estop topic zero
// every robot within one control cycle and hold the run until reset.
#include "exec_common.h"

using namespace exec_test;

namespace {

/// Every robot is zeroed for an e-stop at `event`: by the coordinator itself at once (in
/// [event, by]), and by the follower within its control cycle under way (at most one more
/// command, then zeros; counted in its cycles, not in wall time). Returns the latest
/// coordinator zero after `event`, in seconds.
double expectAllStopped(Watcher& w, const ros::Time& event, const ros::Time& by) {
  double worst_s = 0;
  for (const auto& [robot, cmds] : w.wheels()) {
    const ros::Time zero = firstZeroAfter(from(cmds, "/coordinator"), event);
    EXPECT_NE(zero, ros::Time()) << robot << ": the coordinator published no zero after the e-stop";
    EXPECT_LE(zero, by) << robot << ": the coordinator's zero came " << (zero - event).toSec() << " s after the e-stop";
    worst_s = std::max(worst_s, (zero - event).toSec());
    EXPECT_TRUE(zeroWithinOneCycle(from(cmds, "/path_follower"), event)) << robot << " (the follower)";
    EXPECT_TRUE(cmds.back().zero()) << robot;
  }
  return worst_s;
}

/// Waits until every robot of `spec` has a zero from the coordinator and, where the
/// follower drove it, one from the follower, stamped after `event`. The stamps judge how
/// fast each stopped; arrival only has to happen (under load a message may take long).
bool zerosArrived(Watcher& w, const ddace::task::TaskSpec& spec, const ros::Time& event) {
  return waitFor(
      [&] {
        const auto wheels = w.wheels();
        for (const auto& e : spec.entities) {
          if (e.kind != ddace::task::EntityKind::Robot) continue;
          auto it = wheels.find(e.name);
          if (it == wheels.end() || firstZeroAfter(from(it->second, "/coordinator"), event) == ros::Time())
            return false;
          const auto follower = from(it->second, "/path_follower");
          if (!follower.empty() && (follower.back().stamp <= event || !follower.back().zero())) return false;
        }
        return true;
      },
      10.0);
}

bool anyDriving(Watcher& w) {
  for (const auto& [robot, cmds] : w.wheels())
    if (!cmds.empty() && !cmds.back().zero()) return true;
  return false;
}

}  // namespace

TEST(ExecEstop, ServiceAndTopicZeroEveryRobotWithinOneCycle) {
  TaskGraph g("estop", "task4", 3, 1);
  Watcher w(g.nh, g.test.spec);
  Launch graph(g.args({"monitor:=false", "config:=" + g.files.config_file}));
  const std::string started = startRun(w, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING && anyDriving(w); }, 20.0));
  ros::Duration(0.5).sleep();

  // 1. The service.
  const ros::Time call = ros::Time::now();
  std_srvs::Trigger t;
  ASSERT_TRUE(ros::service::call("/coordinator/estop", t));
  // The coordinator has published the e-stop when the call returns.
  const ros::Time returned = ros::Time::now();
  EXPECT_TRUE(t.response.success) << t.response.message;
  EXPECT_TRUE(zerosArrived(w, g.test.spec, call)) << "the zeros after the e-stop did not arrive within 10 s";
  EXPECT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ESTOPPED; }, 5.0));
  // The coordinator zeroes every robot before it answers.
  std::cout << "~estop: every robot zeroed by the coordinator " << expectAllStopped(w, call, returned)
            << " s after the call\n";
  waitFor(
      [&] {
        for (const auto& [id, s] : w.segments())
          if (s.ended == ros::Time()) return false;
        return true;
      },
      10.0);
  for (const auto& [id, s] : w.segments())
    EXPECT_NE(s.ended, ros::Time()) << s.key << " (segment " << id << ") never ended after the e-stop";
  const size_t requests = w.requests();
  EXPECT_FALSE(trigger("/coordinator/start", 0.5)) << "start must be refused until reset";
  ros::Duration(1.0).sleep();
  EXPECT_EQ(w.requests(), requests) << "a decision was requested while e-stopped";

  // 2. Reset releases it; a new run drives again.
  ASSERT_TRUE(trigger("/coordinator/reset", 5.0));
  EXPECT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::IDLE; }, 2.0));
  ASSERT_TRUE(trigger("/coordinator/start", 10.0));
  ASSERT_TRUE(waitFor([&] { return anyDriving(w); }, 20.0)) << "robots do not drive after reset + start";

  // 3. The latched topic, from anybody.
  ros::Publisher estop = g.nh.advertise<std_msgs::Bool>("/ddace/estop", 1, true);
  ASSERT_TRUE(waitFor([&] { return estop.getNumSubscribers() >= 3; }, 5.0));  // follower, mock, coordinator
  std_msgs::Bool on;
  on.data = true;
  w.clearStates();
  const ros::Time pub = ros::Time::now();
  estop.publish(on);
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::ESTOPPED; }, 5.0));
  EXPECT_TRUE(zerosArrived(w, g.test.spec, pub)) << "the zeros after the e-stop did not arrive within 10 s";
  // The coordinator zeroes in the callback that receives the e-stop, before it announces it.
  std::cout << "/ddace/estop: every robot zeroed by the coordinator "
            << expectAllStopped(w, pub, w.firstStamp(ddace::CoordinatorState::ESTOPPED)) << " s after the message\n";
  EXPECT_EQ(w.stateCode(), ddace::CoordinatorState::ESTOPPED);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_estop_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
