// rostest: scripted truth -> synthetic_camera_node -> tracker_node -> recorder_node,
// labels on /ddace/labels, start/stop services; the result is read back and checked.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <mutex>
#include <regex>

#include <ros/ros.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include "ddace/Label.h"
#include "ddace/task/task_dir.h"
#include "vision_scene.h"

namespace {

struct Scene {
  ros::Publisher truth, labels;
  ros::Time start;
  /// The robots rest (at their circles' time 1 s) until the recording has started (the
  /// recorder starts only from a scene at rest), then drive their circles.
  std::atomic<double> moving_from{1e9};
  double circleTime(double t) const { return 1.0 + std::max(0.0, t - moving_from.load()); }
  void tick(const ros::WallTimerEvent&) {
    const ros::Time now = ros::Time::now();
    truth.publish(vision_test::truthMsg(circleTime((now - start).toSec()), now));
  }
  void label(const std::string& entity, const std::string& action, const std::string& target) {
    ddace::Label l;
    l.header.stamp = ros::Time::now();
    l.entity = entity;
    l.action = action;
    l.target = target;
    labels.publish(l);
  }
};

/// Sleeps until `t` seconds after the scene's start.
void until(const Scene& s, double t) {
  while (ros::ok() && (ros::Time::now() - s.start).toSec() < t) ros::WallDuration(0.005).sleep();
}

}  // namespace

TEST(VisionRecorder, RecordsAValidDemonstrationOfTheMotionAndLabels) {
  ros::NodeHandle nh, pnh("~");
  std::string dir;
  ASSERT_TRUE(pnh.getParam("dir", dir));
  Scene scene;
  scene.truth = nh.advertise<ddace::EntityArray>("/ddace/true_entities", 10);
  scene.labels = nh.advertise<ddace::Label>("/ddace/labels", 10);
  ros::ServiceClient start = nh.serviceClient<std_srvs::Trigger>("/recorder/start");
  ros::ServiceClient stop = nh.serviceClient<std_srvs::Trigger>("/recorder/stop");
  ASSERT_TRUE(start.waitForExistence(ros::Duration(20.0))) << "recorder_node did not come up";
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while ((scene.truth.getNumSubscribers() == 0 || scene.labels.getNumSubscribers() == 0) &&
         ros::WallTime::now() < deadline)
    ros::WallDuration(0.05).sleep();
  ASSERT_GT(scene.truth.getNumSubscribers(), 0u);

  // Before the tracker has seen anything the recorder refuses to start, and says why.
  std_srvs::Trigger trig;
  ASSERT_TRUE(start.call(trig));
  EXPECT_FALSE(trig.response.success);
  EXPECT_NE(trig.response.message.find("/ddace/entities"), std::string::npos) << trig.response.message;

  scene.start = ros::Time::now();
  ros::WallTimer timer = nh.createWallTimer(ros::WallDuration(0.02), &Scene::tick, &scene);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  until(scene, 1.0);
  // The tracker needs a moment to see every marker at rest.
  while (ros::ok() && (ros::Time::now() - scene.start).toSec() < 10.0 && !(start.call(trig) && trig.response.success))
    ros::WallDuration(0.1).sleep();
  ASSERT_TRUE(trig.response.success) << trig.response.message;
  const double started = (ros::Time::now() - scene.start).toSec();
  scene.moving_from = started;
  until(scene, 1.6);
  scene.label("R1", "move", "R3");
  scene.label("R2", "move", "R3");
  until(scene, 2.6);
  scene.label("R1", "idle", "");
  scene.label("R2", "", "");
  until(scene, 2.8);
  scene.label("R3", "stop", "");
  scene.label("G1", "move", "R1");  // refused (a goal), must not break anything
  until(scene, 3.2);
  scene.label("R3", "idle", "");
  until(scene, 3.6);
  ASSERT_TRUE(stop.call(trig));
  timer.stop();
  ASSERT_TRUE(trig.response.success) << trig.response.message;

  // "saved <path>: N rows, D s, start stamp S"
  std::smatch m;
  const std::string msg = trig.response.message;
  ASSERT_TRUE(std::regex_search(msg, m, std::regex(R"(saved (\S+): (\d+) rows, \S+ s, start stamp ([0-9.]+))"))) << msg;
  const std::string path = m[1];
  const double t0 = std::stod(m[3]) - scene.start.toSec();  // CSV t = 0 in scene time
  EXPECT_NEAR(t0, started, 0.2);
  EXPECT_EQ(std::filesystem::path(path).parent_path().parent_path(), std::filesystem::path(dir));

  const ddace::task::TaskDirReport report = ddace::task::checkTaskDir(dir);
  ASSERT_TRUE(report.errors.empty()) << ddace::formatDiagnostics(report.errors);
  ASSERT_EQ(report.dir.demos.size(), 1u);
  const ddace::task::Demonstration& d = report.dir.demos[0];
  const auto& spec = report.dir.spec;
  ASSERT_EQ(spec.entityNames(), (std::vector<std::string>{"R1", "R2", "R3", "R4", "G1"}));
  EXPECT_GE(d.rows(), 30u) << "2.6 s at the camera's 20 Hz";
  EXPECT_EQ(std::to_string(d.rows()), std::string(m[2]));

  // Positions: the truth at each row's time.
  double max_err = 0;
  for (size_t r = 0; r < d.rows(); ++r) {
    const double t = scene.circleTime(t0 + d.t[r]);
    for (int i = 0; i < 5; ++i) {
      double x, y, th;
      vision_test::truePose(i, t, x, y, th);
      const double err =
          std::hypot(d.positions[r][static_cast<size_t>(i)].x() - x, d.positions[r][static_cast<size_t>(i)].y() - y);
      if (err > 0.005) std::printf("  row %zu (t = %.3f) %s: %.1f mm off\n", r, t, vision_test::kNames[i], err * 1000);
      max_err = std::max(max_err, err);
    }
  }
  EXPECT_LT(max_err, 0.005) << "max position error " << max_err * 1000 << " mm";

  // Labels: two steps at the times they were given.
  ASSERT_EQ(d.steps.size(), 2u);
  ASSERT_EQ(d.steps[0].tokens.size(), 2u);
  EXPECT_EQ(ddace::task::tokenKey(d.steps[0].tokens[0], spec), "R1:move:R3");
  EXPECT_EQ(ddace::task::tokenKey(d.steps[0].tokens[1], spec), "R2:move:R3");
  EXPECT_NEAR(t0 + d.t[static_cast<size_t>(d.steps[0].keyframe_row)], 1.6, 0.15);
  ASSERT_EQ(d.steps[1].tokens.size(), 1u);
  EXPECT_EQ(ddace::task::tokenKey(d.steps[1].tokens[0], spec), "R3:stop");
  EXPECT_NEAR(t0 + d.t[static_cast<size_t>(d.steps[1].keyframe_row)], 2.8, 0.15);
  std::printf("vision_recorder: %zu rows, max position error %.2f mm\n", d.rows(), max_err * 1000);
  std::filesystem::remove_all(dir);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "vision_recorder_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
