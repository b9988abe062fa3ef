// The fetch family through launch/execute_real.launch with sim:=true: the real-robot graph
// (tracker, hamster bridge, coordinator, sequence, gp_path, path follower, carried_objects)
// on a simulated table with bodies. Nothing moves the box but its carrier's body pushing it
// (sim_table_node), nothing tells the coordinator where it is but the tracker's
// measurements of the synthetic camera's images, and nothing but carried_objects reports
// its segments. The run must finish as the ground truth says, the box truly on its goal.
#include "exec_common.h"

#include <cmath>
#include <mutex>

namespace {

/// Demonstrations the model is trained on: who fetches is decided by the scene.
constexpr int kTrainDemos = 20;

}  // namespace

TEST(SimFetch, ExecuteRealSimCarriesTheBoxToItsGoal) {
  ros::NodeHandle nh, pnh("~");
  const exec_test::Files files = exec_test::Files::fromParams();
  std::string markers;
  ASSERT_TRUE(pnh.getParam("markers_file", markers)) << "the .test file must set ~markers_file";
  const exec_test::ScratchDir scratch("sim_fetch");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "fetch", kTrainDemos, 1);
  const std::string model = exec_test::trainModel(dir);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");

  std::mutex mu;
  std::map<uint32_t, ddace::SegmentStatus> box_status;
  const exec_test::TrueTable truth(nh);
  ros::Subscriber box_sub =
      nh.subscribe<ddace::SegmentStatus>("/robots/B1/segment_status", 20, [&](const ddace::SegmentStatus::ConstPtr& m) {
        const std::lock_guard<std::mutex> l(mu);
        box_status[m->segment_id] = *m;
      });

  exec_test::Watcher watch(nh, test.spec);
  exec_test::Launch graph(
      {files.launch_file, "task:=" + dir + "/test", "model:=" + model, "sim:=true", "autostart:=false",
       "monitor:=false", "execution:=" + files.config_file, "markers:=" + markers, "mock_link_dir:=" + dir + "/links"},
      dir + "/launch.log");
  const exec_test::RunEnd run = exec_test::runToEnd(watch, 40.0, 100.0);
  auto first_truth = truth.first(), last_truth = truth.last();
  const auto where = [&] {  // the true poses, for a failure's message
    std::string w;
    for (const auto& [name, e] : last_truth)
      w += " " + name + " (" + std::to_string(first_truth[name].pose.x) + ", " +
           std::to_string(first_truth[name].pose.y) + ") -> (" + std::to_string(e.pose.x) + ", " +
           std::to_string(e.pose.y) + ")";
    return w;
  };
  ASSERT_TRUE(exec_test::finished(run)) << where();
  const ddace::CoordinatorState& s = run.state;
  EXPECT_EQ(exec_test::executedSteps(s), exec_test::truthSteps(test.demos.front(), test.spec));
  EXPECT_TRUE(exec_test::goalConditionsMet(s));

  const std::lock_guard<std::mutex> l(mu);
  // carried_objects reported the box's carry DONE.
  bool box_done = false;
  for (const auto& [id, st] : box_status) box_done = box_done || st.status == ddace::SegmentStatus::DONE;
  EXPECT_TRUE(box_done) << "no DONE from carried_objects for B1";
  // The box truly moved on the simulated table, and ends at its goal.
  ASSERT_TRUE(first_truth.count("B1") && last_truth.count("G1"));
  const auto& b0 = first_truth["B1"].pose;
  const auto& b1 = last_truth["B1"].pose;
  const auto& g = last_truth["G1"].pose;
  EXPECT_GT(std::hypot(b1.x - b0.x, b1.y - b0.y), 0.1) << "B1 was not pushed";
  EXPECT_LT(std::hypot(b1.x - g.x, b1.y - g.y), 0.05) << "B1 truly at G1";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_fetch_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
