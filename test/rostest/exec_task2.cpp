// Learned Task 2 (11 robots) end-to-end on mock robots with a model trained in the set-up: the whole graph of
// launch/execute_sim.launch.
#include "exec_common.h"

TEST(ExecTask2, CompletesWithTheGroundTruthSequenceAndEveryGoalCondition) {
  exec_test::runTaskEndToEnd("task2", 11, true, 90.0);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_task2_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
