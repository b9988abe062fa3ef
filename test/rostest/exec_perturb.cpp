// A run perturbed by a hand through launch/execute_sim.launch as shipped (recovery on by
// default, coordinator/max_replans): fetch replayed on mock robots with bodies. While the
// fetcher drives to the box, the box is put down 6 cm away (more than the arrival radius):
// the coordinator re-plans the fetcher's token to where the box is now. While it carries
// the box, the carrier's wheels are held for 5 s. The run finishes with the box on its goal.
// Every wait is on a condition seen on the wire; the hold is the only fixed time. Then a
// robot lost for good on its way to the box (second test).
#include <cmath>

#include <std_msgs/String.h>

#include <ddace/EntityArray.h>

#include "exec_common.h"

namespace {

/// The latest tracked pose of every entity.
class Poses {
 public:
  explicit Poses(ros::NodeHandle& nh)
      : sub_(nh.subscribe<ddace::EntityArray>("/ddace/entities", 10, [this](const ddace::EntityArray::ConstPtr& m) {
          const std::lock_guard<std::mutex> l(mu_);
          for (const auto& e : m->entities) latest_[e.name] = e;
        })) {}
  std::map<std::string, ddace::Entity> latest() const {
    const std::lock_guard<std::mutex> l(mu_);
    return latest_;
  }

 private:
  mutable std::mutex mu_;
  std::map<std::string, ddace::Entity> latest_;
  ros::Subscriber sub_;
};

double distance(const ddace::Entity& a, const ddace::Entity& b) {
  return std::hypot(a.pose.x - b.pose.x, a.pose.y - b.pose.y);
}

/// The first segment sent whose key ends with `suffix` ("" when none yet).
std::string sentKey(exec_test::Watcher& w, const std::string& suffix) {
  for (const auto& [id, s] : w.segments())
    if (s.key.size() >= suffix.size() && s.key.compare(s.key.size() - suffix.size(), suffix.size(), suffix) == 0)
      return s.key;
  return "";
}

int sentCount(exec_test::Watcher& w, const std::string& key) {
  int n = 0;
  for (const auto& [id, s] : w.segments()) n += s.key == key;
  return n;
}

}  // namespace

TEST(ExecPerturb, ABoxMovedAndACarrierHeldAreRecoveredFromAndTheRunFinishes) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("perturb");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "fetch", 3, 1);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  Poses poses(nh);
  ros::Publisher place = nh.advertise<ddace::Entity>("/mock_robots/place", 1, true);
  ros::Publisher hold = nh.advertise<std_msgs::String>("/mock_robots/hold", 1);
  ros::Publisher release = nh.advertise<std_msgs::String>("/mock_robots/release", 1);
  exec_test::Watcher watch(nh, test.spec);
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "train:=" + dir + "/train", "autostart:=false",
                           "monitor:=false", "config:=" + files.config_file},
                          dir + "/launch.log");
  ASSERT_TRUE(exec_test::waitFor(
      [&] { return place.getNumSubscribers() > 0 && hold.getNumSubscribers() > 0 && release.getNumSubscribers() > 0; },
      30.0))
      << "mock_robots does not listen on ~place, ~hold, ~release";
  const std::string started = exec_test::startRun(watch, 30.0);
  ASSERT_TRUE(started.empty()) << started;

  // The fetch: once the fetcher has driven 3 cm toward the box, a hand moves the box 6 cm
  // sideways (the side farther from every other entity).
  std::string fetch;
  ASSERT_TRUE(exec_test::waitFor([&] { return !(fetch = sentKey(watch, ":move:B1")).empty(); }, 30.0))
      << "no robot was sent to B1";
  const std::string fetcher = fetch.substr(0, fetch.find(':'));
  const auto at_start = poses.latest();
  ASSERT_TRUE(at_start.count(fetcher) && at_start.count("B1"));
  ASSERT_TRUE(
      exec_test::waitFor([&] { return distance(poses.latest().at(fetcher), at_start.at(fetcher)) > 0.03; }, 30.0))
      << fetcher << " did not drive toward B1";
  const auto now = poses.latest();
  const ddace::Entity& box = now.at("B1");
  const double bx = box.pose.x - now.at(fetcher).pose.x, by = box.pose.y - now.at(fetcher).pose.y;
  const double n = std::hypot(bx, by);
  ddace::Entity moved = box;
  double clearest = -1;
  for (const double side : {1.0, -1.0}) {
    ddace::Entity c = box;
    c.pose.x += side * -by / n * 0.06;
    c.pose.y += side * bx / n * 0.06;
    double nearest = 1e9;
    for (const auto& [name, e] : now)
      if (name != "B1") nearest = std::min(nearest, distance(c, e));
    if (nearest > clearest) clearest = nearest, moved = c;
  }
  place.publish(moved);
  ASSERT_TRUE(exec_test::waitFor([&] { return distance(poses.latest().at("B1"), moved) < 0.01; }, 10.0))
      << "B1 was not put down where the hand put it";
  EXPECT_TRUE(exec_test::waitFor([&] { return sentCount(watch, fetch) >= 2; }, 20.0))
      << fetch << " was not re-planned after B1 moved 6 cm; state " << watch.state().state_name << ": "
      << watch.state().reason;

  // The carry: its carrier's wheels held for 5 s, then freed.
  std::string carry;
  ASSERT_TRUE(exec_test::waitFor([&] { return !(carry = sentKey(watch, ":carry:G1")).empty(); }, 60.0))
      << "B1 was never carried; state " << watch.state().state_name << ": " << watch.state().reason;
  std_msgs::String carrier;
  carrier.data = carry.substr(0, carry.find(':'));
  hold.publish(carrier);
  ros::Duration(5.0).sleep();
  release.publish(carrier);

  const exec_test::RunEnd run = exec_test::waitRunEnd(watch, 90.0);
  ASSERT_TRUE(exec_test::finished(run));
  const ddace::CoordinatorState& s = run.state;
  EXPECT_TRUE(exec_test::goalConditionsMet(s));
  EXPECT_TRUE(exec_test::wheelsStopped(watch));
}

// With a policy that reads the scene (deliver's scene network), the robot sent to the box
// dies on its way (~lose: its wheels stop, the tracker holds its last pose, stale). The
// coordinator declares it lost for good and decides the step again without it; the other
// robot fetches the box past the dead one -- the path follower keeps it as an obstacle where
// it was last seen, not a stale pose that stops every robot near it -- and the run finishes.
TEST(ExecPerturb, ARobotLostForGoodIsLeftWhereItDiedAndTheOtherDoesItsWork) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("perturb_lost");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "deliver", 20, 1);
  const std::string model = exec_test::trainModel(dir);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  Poses poses(nh);
  ros::Publisher lose = nh.advertise<std_msgs::String>("/mock_robots/lose", 1);
  exec_test::Watcher watch(nh, test.spec);
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "model:=" + model, "autostart:=false",
                           "monitor:=false", "config:=" + files.config_file},
                          dir + "/launch.log");
  ASSERT_TRUE(exec_test::waitFor([&] { return lose.getNumSubscribers() > 0; }, 30.0))
      << "mock_robots does not listen on ~lose";
  const std::string started = exec_test::startRun(watch, 30.0);
  ASSERT_TRUE(started.empty()) << started;
  std::string fetch;
  ASSERT_TRUE(exec_test::waitFor([&] { return !(fetch = sentKey(watch, ":move:B1")).empty(); }, 30.0))
      << "no robot was sent to B1";
  std_msgs::String dead;
  dead.data = fetch.substr(0, fetch.find(':'));
  // Near the box (12 cm between centres): whoever fetches it next comes well within the
  // safety filter's range of the dead robot.
  ASSERT_TRUE(exec_test::waitFor(
      [&] {
        const auto p = poses.latest();
        return p.count(dead.data) && p.count("B1") && distance(p.at(dead.data), p.at("B1")) < 0.12;
      },
      30.0))
      << dead.data << " did not drive to B1";
  lose.publish(dead);

  const exec_test::RunEnd run = exec_test::waitRunEnd(watch, 90.0);
  ASSERT_TRUE(exec_test::finished(run));
  const ddace::CoordinatorState& s = run.state;
  EXPECT_EQ(s.lost, std::vector<std::string>{dead.data}) << "the coordinator did not declare it lost";
  EXPECT_TRUE(exec_test::goalConditionsMet(s));
  bool other_fetched = false;
  for (const auto& [id, seg] : watch.segments())
    other_fetched |= seg.key.rfind(dead.data + ":", 0) != 0 && seg.key.find(":move:B1") != std::string::npos;
  EXPECT_TRUE(other_fetched) << "the other robot was never sent to B1";
  EXPECT_TRUE(exec_test::wheelsStopped(watch));
}

int main(int argc, char** argv) {
  return exec_test::rostestMain(argc, argv, "exec_perturb_test");
}
