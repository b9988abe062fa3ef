// Async dispatch through the launch file: Task 4's demonstration replayed on mock robots
// with `coordinator/dispatch: async`. A replay is a fixed order, so the coordinator decides
// ahead and starts each token when its own predecessors (learned from the training
// demonstrations) have ended. Judged from the wire only: the run finishes with the
// ground-truth steps and every goal condition, and no segment went out before a DONE of
// each token it waits for (the executors' stamps precede the coordinator's, whatever the load).
#include "exec_common.h"

#include "ddace/graph/dependencies.h"

TEST(ExecAsync, FinishesTask4AndNeverSendsASegmentBeforeItsPredecessorsEnded) {
  ros::NodeHandle nh;
  const exec_test::Files files = exec_test::Files::fromParams();
  const exec_test::ScratchDir scratch("async");
  const std::string& dir = scratch;
  exec_test::generateTask(dir, "task4", 3, 1, 4);
  const std::string config =
      exec_test::writeConfig(files.config_file, dir + "/execution.yaml", {{{"coordinator", "dispatch", "async"}}});
  const ddace::task::TaskDir train = ddace::task::loadTaskDir(dir + "/train");
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  const ddace::graph::Dependencies deps = ddace::graph::learnDependencies(train.spec, train.demos);
  ASSERT_TRUE(deps.learned);
  exec_test::Watcher watch(nh, test.spec);
  exec_test::Launch graph({files.launch_file, "task:=" + dir + "/test", "train:=" + dir + "/train", "autostart:=false",
                           "monitor:=false", "config:=" + config});
  const exec_test::RunEnd run = exec_test::runToEnd(watch, 30.0, 90.0);
  ASSERT_TRUE(exec_test::finished(run));
  const ddace::CoordinatorState& s = run.state;
  const auto truth = exec_test::truthSteps(test.demos.front(), test.spec);
  EXPECT_EQ(exec_test::executedSteps(s), truth);
  EXPECT_TRUE(exec_test::goalConditionsMet(s));
  EXPECT_EQ(watch.requests(), test.demos.front().steps.size() + 1) << "one decision per step plus END";

  // Precedence, from the stamps on the wire.
  std::vector<std::vector<ddace::task::Token>> steps;
  for (const auto& keys : truth) {
    steps.emplace_back();
    for (const auto& k : keys) steps.back().push_back(ddace::task::parseTokenKey(k, test.spec));
  }
  const auto index = [&](int step, const std::string& key) {
    const auto& keys = truth.at(static_cast<size_t>(step));
    return static_cast<size_t>(std::find(keys.begin(), keys.end(), key) - keys.begin());
  };
  const auto segs = watch.segments();
  int checked = 0;
  for (const auto& [id_b, b] : segs)
    for (const auto& [id_a, a] : segs) {
      if (b.step < 0 || a.step < 0 || a.step >= b.step || b.sent == ros::Time()) continue;
      const size_t ib = index(b.step, b.key), ia = index(a.step, a.key);
      ASSERT_LT(ib, steps[static_cast<size_t>(b.step)].size()) << b.key;
      ASSERT_LT(ia, steps[static_cast<size_t>(a.step)].size()) << a.key;
      if (!deps.waitsFor(test.spec, steps[static_cast<size_t>(b.step)], ib, steps[static_cast<size_t>(a.step)], ia))
        continue;
      ++checked;
      EXPECT_NE(a.ended, ros::Time()) << b.key << " went out but " << a.key << " never ended";
      EXPECT_LE(a.ended, b.sent) << b.key << " (step " << b.step + 1 << ") went out before " << a.key << " (step "
                                 << a.step + 1 << ") ended";
    }
  EXPECT_GT(checked, 0) << "no segment waited for another";
  EXPECT_TRUE(exec_test::wheelsStopped(watch));
}

int main(int argc, char** argv) {
  return exec_test::rostestMain(argc, argv, "exec_async_test");
}
