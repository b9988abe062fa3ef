// launch/record.launch sim:=true with the files of a task of one's own, as `ddace init`
// writes them (robots R1, R2 and goal G1, laid out in rows; recorded into the task
// directory init made, whose task.yaml the recorder accepts): a start while R2 still moves
// is refused, naming R2; then the test drags R2 onto G1 as a person in rviz does (interactive marker feedback on
// /sim_table/drag/feedback: R2's marker dropped on G1), between /recorder/start and /recorder/stop. The saved
// demonstration must hold that motion as the tracker saw it
// -- R2 from its row onto G1, the others still -- and the label the recorder inferred
// from it: R2 moves to G1. Then a person's own tool: scripts/sim_teleop.py on a
// pseudo-terminal, keys typed, drives R1 forward and stops it; the same tool under another
// node name moves nothing (the simulated robots obey their command sources only).
#include "exec_common.h"

#include <fcntl.h>
#include <poll.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>

#include <visualization_msgs/InteractiveMarkerFeedback.h>

namespace {

struct Pose {
  double x = 0, y = 0, theta = 0;
};

/// A program on a new pseudo-terminal (its controlling terminal and stdin/stdout), as a
/// person's terminal window: keys are typed into it, its output is collected.
class Terminal {
 public:
  explicit Terminal(const std::vector<std::string>& argv) {
    master_ = posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || grantpt(master_) != 0 || unlockpt(master_) != 0) return;
    const std::string slave_name = ptsname(master_);
    pid_ = fork();
    if (pid_ == 0) {
      setsid();
      const int slave = open(slave_name.c_str(), O_RDWR);
      dup2(slave, 0), dup2(slave, 1), dup2(slave, 2);
      close(master_);
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
  }
  ~Terminal() {
    if (pid_ > 0 && waitpid(pid_, nullptr, WNOHANG) == 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    if (master_ >= 0) close(master_);
  }
  /// Reads what it printed until `text` appears (true) or `timeout_s` passes.
  bool waitOutput(const std::string& text, double timeout_s) {
    return exec_test::waitFor(
        [&] {
          char buf[4096];
          pollfd p{master_, POLLIN, 0};
          if (poll(&p, 1, 20) > 0) {
            const ssize_t n = read(master_, buf, sizeof buf);
            if (n > 0) output_.append(buf, static_cast<size_t>(n));
          }
          return output_.find(text) != std::string::npos;
        },
        timeout_s);
  }
  bool type(const std::string& keys) {
    return write(master_, keys.data(), keys.size()) == static_cast<ssize_t>(keys.size());
  }
  /// The exit status once it ended within `timeout_s`, else -1.
  int exitStatus(double timeout_s) {
    int status = -1;
    const bool ended = exec_test::waitFor([&] { return waitpid(pid_, &status, WNOHANG) == pid_; }, timeout_s);
    if (!ended) return -1;
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  const std::string& output() const { return output_; }

 private:
  int master_ = -1;
  pid_t pid_ = -1;
  std::string output_;
};

}  // namespace

TEST(SimRecord, RecordsARobotDrivenOnTheSimulatedTable) {
  ros::NodeHandle nh, pnh("~");
  std::string launch_file, teleop;
  ASSERT_TRUE(pnh.getParam("launch_file", launch_file));
  ASSERT_TRUE(pnh.getParam("teleop", teleop));
  const exec_test::ScratchDir scratch("sim_record");
  const std::string& dir = scratch;
  const std::string out = dir + "/own_task";
  const std::string tool = (std::filesystem::read_symlink("/proc/self/exe").parent_path() / "ddace").string();
  ASSERT_EQ(std::system(
                ("'" + tool + "' init '" + out + "' --robots R1,R2 --goals G1 > '" + dir + "/init.log' 2>&1").c_str()),
            0)
      << "ddace init failed (" << dir << "/init.log)";

  std::mutex mu;
  std::map<std::string, Pose> truth;
  ros::Subscriber truth_sub =
      nh.subscribe<ddace::EntityArray>("/ddace/true_entities", 10, [&](const ddace::EntityArray::ConstPtr& m) {
        const std::lock_guard<std::mutex> l(mu);
        for (const auto& e : m->entities) truth[e.name] = {e.pose.x, e.pose.y, e.pose.theta};
      });
  ros::Publisher wheels = nh.advertise<ddace::WheelCommand>("/robots/R2/wheels", 5);
  ros::Publisher drag = nh.advertise<visualization_msgs::InteractiveMarkerFeedback>("/sim_table/drag/feedback", 5);

  exec_test::Launch graph({launch_file, "sim:=true", "keyboard:=false", "teleop:=false", "rviz:=false",
                           "markers:=" + out + "/config/markers.yaml", "recorder:=" + out + "/config/recorder.yaml",
                           "command_sources:=[/sim_teleop, " + ros::this_node::getName() + "]"},
                          dir + "/launch.log");
  auto drive = [&](double left, double right) {
    ddace::WheelCommand c;
    c.header.stamp = ros::Time::now();
    c.left_mps = left;
    c.right_mps = right;
    wheels.publish(c);
  };
  ASSERT_TRUE(exec_test::waitFor([&] { return wheels.getNumSubscribers() == 1u; }, 40.0))
      << "sim_table does not listen to /robots/R2/wheels";

  // A start while a robot still moves is refused, naming it: R2 rocks back and forth (5 cm)
  // until the recorder has named it; then it rests, and the start goes through.
  std::string message;
  bool started_moving = false;
  const auto rocking = ros::WallTime::now();
  const bool named = exec_test::waitFor(
      [&] {
        const double v = std::fmod((ros::WallTime::now() - rocking).toSec(), 1.0) < 0.5 ? 0.1 : -0.1;
        drive(v, v);
        ros::WallDuration(0.05).sleep();
        std_srvs::Trigger t;
        if (!ros::service::exists("/recorder/start", false) || !ros::service::call("/recorder/start", t)) return false;
        message = t.response.message;
        started_moving = t.response.success;
        return started_moving || message.find("R2 moved within the last") != std::string::npos;
      },
      40.0);
  drive(0, 0);
  ASSERT_FALSE(started_moving) << "the recorder started while R2 moved: " << message;
  ASSERT_TRUE(named) << "the recorder's refusal does not name R2: " << message;
  std::cout << "sim_record: " << message << "\n";
  ASSERT_TRUE(exec_test::trigger("/recorder/start", 40.0, &message)) << "the recorder did not start: " << message;
  std::map<std::string, Pose> start;
  {
    const std::lock_guard<std::mutex> l(mu);
    start = truth;
  }
  ASSERT_TRUE(start.count("R2") && start.count("G1"));

  // Drag R2 onto G1 in "rviz": press on its marker, move it there, let go.
  ASSERT_TRUE(exec_test::waitFor([&] { return drag.getNumSubscribers() > 0u; }, 10.0))
      << "sim_table serves no drag markers on /sim_table/drag";
  for (const uint8_t event : {visualization_msgs::InteractiveMarkerFeedback::MOUSE_DOWN,
                              visualization_msgs::InteractiveMarkerFeedback::POSE_UPDATE,
                              visualization_msgs::InteractiveMarkerFeedback::MOUSE_UP}) {
    visualization_msgs::InteractiveMarkerFeedback f;
    f.header.frame_id = "table";
    f.header.stamp = ros::Time::now();
    f.client_id = "/rviz/InteractiveMarkers";
    f.marker_name = "R2";
    f.control_name = "move";
    f.event_type = event;
    f.pose.position.x = start["G1"].x;
    f.pose.position.y = start["G1"].y;
    f.pose.orientation.w = 1;
    drag.publish(f);
    ros::WallDuration(0.1).sleep();
  }
  Pose r2_before_stop;
  const bool arrived = exec_test::waitFor(
      [&] {
        const std::lock_guard<std::mutex> l(mu);
        r2_before_stop = truth["R2"];
        return std::hypot(truth["R2"].x - start["G1"].x, truth["R2"].y - start["G1"].y) < 0.015;
      },
      30.0);
  ASSERT_TRUE(arrived) << "R2 was not driven to G1 where it was dropped; it is at (" << r2_before_stop.x << ", "
                       << r2_before_stop.y << ")";
  ros::Duration(1.5).sleep();  // still at the end, as a person lets go
  ASSERT_TRUE(exec_test::trigger("/recorder/stop", 10.0, &message)) << message;
  std::cout << "sim_record: " << message << "\n";

  const ddace::task::TaskDir task = ddace::task::loadTaskDir(out);
  ASSERT_EQ(task.demos.size(), 1u);
  const ddace::task::Demonstration& demo = task.demos.front();
  const int r2 = task.spec.entityIndex("R2"), g1 = task.spec.entityIndex("G1");
  ASSERT_GE(r2, 0);
  ASSERT_GE(g1, 0);
  ASSERT_GT(demo.rows(), 20u);
  // As the tracker saw it: R2 from where it stood onto G1; every other body still.
  const auto& first = demo.positions.front();
  const auto& last = demo.positions.back();
  EXPECT_LT((first[r2] - Eigen::Vector2d(start["R2"].x, start["R2"].y)).norm(), 0.02);
  EXPECT_LT((last[r2] - last[g1]).norm(), 0.03) << "R2 ends on G1";
  EXPECT_GT((last[r2] - first[r2]).norm(), 0.3);
  for (size_t i = 0; i < task.spec.entities.size(); ++i) {
    if (static_cast<int>(i) == r2) continue;
    EXPECT_LT((last[i] - first[i]).norm(), 0.02) << task.spec.entities[i].name;
  }
  // The recorder inferred the one step a person would label: R2 moves to G1.
  ASSERT_EQ(demo.steps.size(), 1u) << message;
  ASSERT_EQ(demo.steps.front().tokens.size(), 1u) << message;
  EXPECT_EQ(ddace::task::tokenKey(demo.steps.front().tokens.front(), task.spec), "R2:move:G1") << message;

  // The teleop: robot 1 (R1), two steps faster forward (0.1 m/s), then stop, then quit.
  auto r1 = [&] {
    const std::lock_guard<std::mutex> l(mu);
    return truth["R1"];
  };
  Terminal keys({"/usr/bin/python3", teleop});
  ASSERT_TRUE(keys.waitOutput("[R1]", 30.0)) << keys.output();
  const Pose before = r1();
  ASSERT_TRUE(keys.type("1ww"));
  const bool moved = exec_test::waitFor(
      [&] {
        keys.waitOutput("", 0);  // what it shows (the failure's account)
        const Pose p = r1();
        return std::hypot(p.x - before.x, p.y - before.y) > 0.05;
      },
      10.0);
  ASSERT_TRUE(keys.type("s"));
  ASSERT_TRUE(moved) << "R1 did not move on w w: " << keys.output();
  const Pose now = r1();
  EXPECT_GT(now.y - before.y, 0.04) << "R1 drove forward (+y, as it was laid out facing)";
  ros::Duration(1.0).sleep();
  const Pose stopped = r1();
  ros::Duration(1.0).sleep();
  EXPECT_LT(std::hypot(r1().x - stopped.x, r1().y - stopped.y), 0.002) << "R1 stopped on s";
  ASSERT_TRUE(keys.type("q"));
  EXPECT_EQ(keys.exitStatus(10.0), 0) << keys.output();

  // The same tool started under a name the launch did not give it moves nothing: the
  // simulated robots obey their command sources as the real ones do.
  Terminal stranger({"/usr/bin/python3", teleop, "__name:=stranger"});
  ASSERT_TRUE(stranger.waitOutput("[R1]", 30.0)) << stranger.output();
  const Pose parked = r1();
  ASSERT_TRUE(stranger.type("1ww"));
  auto log = [&] {
    std::ifstream f(dir + "/launch.log");
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  };
  EXPECT_TRUE(exec_test::waitFor(
      [&] { return log().find("/robots/R1/wheels: command from /stranger refused") != std::string::npos; }, 20.0))
      << "sim_table did not name the stranger's commands";
  EXPECT_LT(std::hypot(r1().x - parked.x, r1().y - parked.y), 0.002) << "R1 obeyed a node the launch did not name";
  ASSERT_TRUE(stranger.type("q"));
  EXPECT_EQ(stranger.exitStatus(10.0), 0) << stranger.output();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "sim_record_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
