// rostest: a person's demonstration without keys. Scripted truth -> synthetic_camera_node
// -> tracker_node -> recorder_node, no label on /ddace/labels; on ~stop the recorder
// infers the labels from the tracked motion, and the saved demonstration validates with
// the demonstrated steps.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <regex>

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include "ddace/EntityArray.h"
#include "ddace/task/task_dir.h"

namespace {

const char* kNames[5] = {"R1", "R2", "R3", "R4", "G1"};
const double kStart[5][2] = {{0.2, 0.3}, {0.45, 0.2}, {0.6, 0.45}, {0.35, 0.65}, {0.85, 0.8}};
constexpr double kContact = 0.044;  // two Hamsters touch this far apart, centre to centre

/// A straight motion from `from` to `to` during [t0, t1], smooth at both ends.
struct Motion {
  int entity;
  double t0, t1;
  double from[2], to[2];
};

/// The demonstration: step 1, R1 onto G1 and R2 against R4, R2 starting 0.6 s after R1;
/// step 2, R1 from G1 against R3.
std::vector<Motion> script() {
  auto towards = [](const double* from, const double* at, double stop_short, double* to) {
    const double dx = at[0] - from[0], dy = at[1] - from[1], d = std::hypot(dx, dy);
    to[0] = at[0] - dx / d * stop_short;
    to[1] = at[1] - dy / d * stop_short;
  };
  Motion r1{0, 1.6, 4.1, {kStart[0][0], kStart[0][1]}, {kStart[4][0], kStart[4][1]}};
  Motion r2{1, 2.2, 4.4, {kStart[1][0], kStart[1][1]}, {}};
  towards(kStart[1], kStart[3], kContact, r2.to);
  Motion back{0, 5.4, 7.4, {kStart[4][0], kStart[4][1]}, {}};
  towards(kStart[4], kStart[2], kContact, back.to);
  return {r1, r2, back};
}

ddace::EntityArray truthAt(double t, const ros::Time& stamp) {
  static const std::vector<Motion> motions = script();
  ddace::EntityArray msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = "table";
  for (int i = 0; i < 5; ++i) {
    ddace::Entity e;
    e.name = kNames[i];
    e.kind = i == 4 ? "goal" : "robot";
    e.pose.x = kStart[i][0];
    e.pose.y = kStart[i][1];
    for (const auto& m : motions) {
      if (m.entity != i || t < m.t0) continue;
      const double u = std::min(1.0, (t - m.t0) / (m.t1 - m.t0)), s = u * u * (3 - 2 * u);
      e.pose.x = m.from[0] + (m.to[0] - m.from[0]) * s;
      e.pose.y = m.from[1] + (m.to[1] - m.from[1]) * s;
    }
    e.visible = true;
    e.last_seen = stamp;
    msg.entities.push_back(e);
  }
  return msg;
}

struct Scene {
  ros::Publisher truth;
  ros::Time start;
  void tick(const ros::WallTimerEvent&) {
    const ros::Time now = ros::Time::now();
    truth.publish(truthAt((now - start).toSec(), now));
  }
};

void until(const Scene& s, double t) {
  while (ros::ok() && (ros::Time::now() - s.start).toSec() < t) ros::WallDuration(0.005).sleep();
}

}  // namespace

TEST(VisionLabel, InfersTheLabelsOfADemonstrationRecordedWithoutKeys) {
  ros::NodeHandle nh, pnh("~");
  std::string dir;
  ASSERT_TRUE(pnh.getParam("dir", dir));
  Scene scene;
  scene.truth = nh.advertise<ddace::EntityArray>("/ddace/true_entities", 10);
  ros::ServiceClient start = nh.serviceClient<std_srvs::Trigger>("/recorder/start");
  ros::ServiceClient stop = nh.serviceClient<std_srvs::Trigger>("/recorder/stop");
  ASSERT_TRUE(start.waitForExistence(ros::Duration(20.0))) << "recorder_node did not come up";
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (scene.truth.getNumSubscribers() == 0 && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
  ASSERT_GT(scene.truth.getNumSubscribers(), 0u);

  // Every robot at rest until the recording runs (the script's clock starts then).
  scene.start = ros::Time::now() + ros::Duration(1000.0);
  ros::WallTimer timer = nh.createWallTimer(ros::WallDuration(0.02), &Scene::tick, &scene);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  std_srvs::Trigger trig;
  // The tracker needs a moment to see every marker.
  const ros::WallTime seen_by = ros::WallTime::now() + ros::WallDuration(20.0);
  while (ros::WallTime::now() < seen_by && !(start.call(trig) && trig.response.success)) ros::WallDuration(0.2).sleep();
  ASSERT_TRUE(trig.response.success) << trig.response.message;
  scene.start = ros::Time::now();
  until(scene, 8.6);
  ASSERT_TRUE(stop.call(trig));
  timer.stop();
  const std::string msg = trig.response.message;
  ASSERT_TRUE(trig.response.success) << msg;
  EXPECT_NE(msg.find("labels inferred: [R1:move:G1 R2:move:R4] [R1:move:R3]"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("to check"), std::string::npos) << msg;

  std::smatch m;
  ASSERT_TRUE(std::regex_search(msg, m, std::regex(R"(start stamp ([0-9.]+))"))) << msg;
  const double t0 = std::stod(m[1]) - scene.start.toSec();  // CSV t = 0 in scene time
  const ddace::task::TaskDirReport report = ddace::task::checkTaskDir(dir);
  ASSERT_TRUE(report.errors.empty()) << ddace::formatDiagnostics(report.errors);
  ASSERT_EQ(report.dir.demos.size(), 1u);
  const auto& d = report.dir.demos[0];
  const auto& spec = report.dir.spec;
  ASSERT_EQ(d.steps.size(), 2u);
  std::vector<std::string> first, second;
  for (const auto& t : d.steps[0].tokens) first.push_back(ddace::task::tokenKey(t, spec));
  for (const auto& t : d.steps[1].tokens) second.push_back(ddace::task::tokenKey(t, spec));
  EXPECT_EQ(first, (std::vector<std::string>{"R1:move:G1", "R2:move:R4"}));
  EXPECT_EQ(second, (std::vector<std::string>{"R1:move:R3"}));
  // Each step begins when its first robot started.
  EXPECT_NEAR(t0 + d.t[static_cast<size_t>(d.steps[0].keyframe_row)], 1.6, 0.3);
  EXPECT_NEAR(t0 + d.t[static_cast<size_t>(d.steps[1].keyframe_row)], 5.4, 0.3);
  std::filesystem::remove_all(dir);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "vision_label_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
