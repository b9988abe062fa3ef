// MockRobotNode: see include/ddace/ros/mock_robot.h.
#include "ddace/ros/mock_robot.h"

#include <filesystem>
#include <map>
#include <memory>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <tf2/LinearMath/Quaternion.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>

#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "exec_conversions.h"
#include "params.h"
#include "ddace/exec/scene.h"
#include "ddace/task/task_dir.h"

namespace ddace::nodes {

class MockRobotNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = ros_exec::loadTaskSpec(task_path);
    const MockRobotNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    publish_tf_ = rosparam::param(pnh, "publish_tf", defaults.publish_tf);
    object_speed_mps_ = rosparam::param(pnh, "object_speed_mps", defaults.object_speed_mps);
    if (!(object_speed_mps_ > 0))
      throw Error("parameter '" + pnh.resolveName("object_speed_mps") + "' must be positive");
    const exec::DiffDriveParams dp = ros_exec::loadDiffDriveParams(ros::NodeHandle(pnh, "robot"));
    const auto stalled = rosparam::param(pnh, "stalled", std::vector<std::string>{});
    for (const auto& s : stalled)
      if (spec_.entityIndex(s) < 0)
        throw Error("parameter '" + pnh.resolveName("stalled") + "' names '" + s + "', not an entity of the task");

    std::vector<exec::Pose2D> start = loadScene(pnh, task_path);
    const size_t n = spec_.entities.size();
    entities_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      Entity& e = entities_[i];
      e.pose = start[i];
      const auto& te = spec_.entities[i];
      if (te.kind == task::EntityKind::Robot) {
        exec::DiffDriveParams p = dp;
        p.seed = dp.seed + i;  // independent noise per robot
        e.robot = std::make_unique<exec::DiffDriveModel>(p, start[i]);
        if (std::find(stalled.begin(), stalled.end(), te.name) != stalled.end()) {
          e.robot->setStalled(true);
          ROS_WARN("mock_robots: %s is stalled (its wheels do not turn)", te.name.c_str());
        }
        e.wheels_sub = nh.subscribe<ddace::WheelCommand>(
            "/robots/" + te.name + "/wheels", 10, [this, i](const ddace::WheelCommand::ConstPtr& m) {
              entities_[i].robot->command({m->left_mps, m->right_mps}, sim_time_s_);
            });
      } else if (te.kind == task::EntityKind::Object) {
        e.status = nh.advertise<ddace::SegmentStatus>("/robots/" + te.name + "/segment_status", 10);
        e.segment_sub =
            nh.subscribe<ddace::Segment>("/robots/" + te.name + "/segment", 10,
                                         [this, i](const ddace::Segment::ConstPtr& m) { onObjectSegment(i, *m); });
      }
    }
    rate_hz_ = dp.rate_hz;
    const std::string topic = rosparam::param(pnh, "entities_topic", defaults.entities_topic);
    entities_pub_ = nh.advertise<ddace::EntityArray>(topic, 5);
    estop_sub_ = nh.subscribe("/ddace/estop", 5, &Impl::onEstop, this);
    timer_ = nh.createTimer(ros::Duration(1.0 / rate_hz_), &Impl::onTimer, this);
    if (publish_tf_) publishStaticFrames();
    ROS_INFO("mock_robots: task '%s', %zu entities at %.0f Hz on %s", spec_.name.c_str(), n, rate_hz_, topic.c_str());
  }

 private:
  struct Entity {
    exec::Pose2D pose;  ///< objects and goals; robots use `robot`
    std::unique_ptr<exec::DiffDriveModel> robot;
    ros::Subscriber wheels_sub, segment_sub;
    ros::Publisher status;
    std::unique_ptr<exec::CarriedObject> carried;  ///< object segment being carried out
    uint32_t segment_id = 0;
    bool moving = false;
    int status_cycle = 0;
  };

  /// Start poses: a demonstration's first row (`scene_csv`, or demos/ of the task
  /// directory by `scene_demo` index), or a `scene` map name -> [x, y(, yaw)].
  std::vector<exec::Pose2D> loadScene(ros::NodeHandle& pnh, const std::string& task_path) {
    const size_t n = spec_.entities.size();
    std::vector<exec::Pose2D> poses(n);
    std::vector<bool> set(n, false);
    std::string csv = rosparam::param<std::string>(pnh, "scene_csv", "");
    const int demo_index = rosparam::param(pnh, "scene_demo", -1);
    if (csv.empty() && demo_index >= 0)
      csv = task::demoFile(task_path, demo_index, "parameter '" + pnh.resolveName("scene_demo") + "'");
    if (!csv.empty()) {
      poses = exec::startPoses(task::readDemonstrationCsv(csv, spec_));
      set.assign(n, true);
      ROS_INFO("mock_robots: scene from the first row of %s", csv.c_str());
    }
    if (auto scene = rosparam::optionalParam<XmlRpc::XmlRpcValue>(pnh, "scene")) {
      if (scene->getType() != XmlRpc::XmlRpcValue::TypeStruct)
        throw Error("parameter '" + pnh.resolveName("scene") + "' must be a map name: [x, y] or [x, y, yaw]");
      for (auto it = scene->begin(); it != scene->end(); ++it) {
        const int i = spec_.entityIndex(it->first);
        const std::string where = pnh.resolveName("scene") + "/" + it->first;
        if (i < 0) throw Error("parameter '" + where + "': no entity of that name in the task");
        auto& v = it->second;
        if (v.getType() != XmlRpc::XmlRpcValue::TypeArray || (v.size() != 2 && v.size() != 3))
          throw Error("parameter '" + where + "' must be [x, y] or [x, y, yaw]");
        auto num = [&](int k) {
          auto& x = v[k];
          if (x.getType() == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(x);
          if (x.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<double>(static_cast<int>(x));
          throw Error("parameter '" + where + "' element " + std::to_string(k) + " is not a number");
        };
        poses[i] = {num(0), num(1), v.size() == 3 ? num(2) : 0.0};
        set[i] = true;
      }
    }
    for (size_t i = 0; i < n; ++i)
      if (!set[i])
        throw Error("no start pose for entity '" + spec_.entities[i].name + "': set '" + pnh.resolveName("scene_csv") +
                    "', '" + pnh.resolveName("scene_demo") + "' or '" + pnh.resolveName("scene") + "'");
    return poses;
  }

  void objectStatus(Entity& e, size_t i, uint8_t status, const std::string& msg) {
    ddace::SegmentStatus s;
    s.header.stamp = ros::Time::now();
    s.entity = spec_.entities[i].name;
    s.segment_id = e.segment_id;
    s.status = status;
    s.progress = e.carried ? e.carried->progress() : 0.0;
    s.distance_to_goal_m = e.carried ? (e.carried->goal() - e.pose.position()).norm() : 0.0;
    s.message = msg;
    e.status.publish(s);
  }

  void onObjectSegment(size_t i, const ddace::Segment& m) {
    Entity& e = entities_[i];
    if (m.mode == ddace::Segment::MODE_STOP || estopped_) {
      if (e.moving) objectStatus(e, i, ddace::SegmentStatus::ABORTED, estopped_ ? "e-stop" : "stopped");
      e.moving = false;
      if (m.mode != ddace::Segment::MODE_STOP) {
        e.segment_id = m.segment_id;
        objectStatus(e, i, ddace::SegmentStatus::ABORTED, "e-stop is active");
      }
      return;
    }
    if (e.moving && m.segment_id == e.segment_id) return;  // a re-sent copy of the running segment
    try {
      const exec::PlannedPath p =
          ros_exec::fromMsg(m.path, m.stddev_m, "/robots/" + spec_.entities[i].name + "/segment");
      if (p.points.empty()) throw Error("segment path is empty");
      e.carried = std::make_unique<exec::CarriedObject>(p.points, e.pose.position(), object_speed_mps_);
      e.segment_id = m.segment_id;
      e.moving = true;
      objectStatus(e, i, ddace::SegmentStatus::ACCEPTED, "");
    } catch (const std::exception& ex) {
      e.segment_id = m.segment_id;
      e.moving = false;
      objectStatus(e, i, ddace::SegmentStatus::FAILED, ex.what());
    }
  }

  /// Goals never move: their frames go on /tf_static once (latched), not at 50 Hz on /tf.
  void publishStaticFrames() {
    std::vector<geometry_msgs::TransformStamped> frames;
    for (size_t i = 0; i < entities_.size(); ++i) {
      if (spec_.entities[i].kind != task::EntityKind::Goal) continue;
      frames.push_back(transform(spec_.entities[i].name, entities_[i].pose, ros::Time::now()));
    }
    if (!frames.empty()) static_tf_.sendTransform(frames);
  }

  geometry_msgs::TransformStamped transform(const std::string& child, const exec::Pose2D& pose,
                                            const ros::Time& stamp) const {
    geometry_msgs::TransformStamped t;
    t.header.stamp = stamp;
    t.header.frame_id = frame_id_;
    t.child_frame_id = child;
    t.transform.translation.x = pose.x;
    t.transform.translation.y = pose.y;
    tf2::Quaternion q;
    q.setRPY(0, 0, pose.yaw);
    t.transform.rotation.x = q.x();
    t.transform.rotation.y = q.y();
    t.transform.rotation.z = q.z();
    t.transform.rotation.w = q.w();
    return t;
  }

  void onEstop(const std_msgs::Bool& m) {
    estopped_ = m.data;
    if (!estopped_) return;
    for (size_t i = 0; i < entities_.size(); ++i)
      if (entities_[i].moving) {
        entities_[i].moving = false;
        objectStatus(entities_[i], i, ddace::SegmentStatus::ABORTED, "e-stop");
      }
  }

  void onTimer(const ros::TimerEvent&) {
    const double dt = 1.0 / rate_hz_;
    ddace::EntityArray msg;
    msg.header.stamp = ros::Time::now();
    msg.header.frame_id = frame_id_;
    for (size_t i = 0; i < entities_.size(); ++i) {
      Entity& e = entities_[i];
      exec::Pose2D measured = e.pose;
      if (e.robot) {
        e.robot->step();
        measured = e.robot->measuredPose();
        e.pose = e.robot->truePose();
      } else if (e.moving) {
        const Eigen::Vector2d p = e.carried->advance(dt);
        e.pose.x = p.x();
        e.pose.y = p.y();
        measured = e.pose;
        if (e.carried->arrived()) {
          e.moving = false;
          objectStatus(e, i, ddace::SegmentStatus::DONE, "");
        } else if (++e.status_cycle % 5 == 0) {
          objectStatus(e, i, ddace::SegmentStatus::RUNNING, "");
        }
      }
      ddace::Entity out;
      out.name = spec_.entities[i].name;
      out.kind = task::toString(spec_.entities[i].kind);
      out.pose.x = measured.x;
      out.pose.y = measured.y;
      out.pose.theta = measured.yaw;
      out.visible = true;
      out.stale = false;
      out.last_seen = msg.header.stamp;
      msg.entities.push_back(out);
      if (publish_tf_ && spec_.entities[i].kind != task::EntityKind::Goal)
        tf_.sendTransform(transform(out.name, measured, msg.header.stamp));
    }
    sim_time_s_ += dt;
    entities_pub_.publish(msg);
  }

  task::TaskSpec spec_;
  std::vector<Entity> entities_;
  std::string frame_id_;
  bool publish_tf_ = true;  // these three: set from the parameters
  double object_speed_mps_ = 0;
  double rate_hz_ = 0;
  double sim_time_s_ = 0;
  bool estopped_ = false;
  ros::Publisher entities_pub_;
  ros::Subscriber estop_sub_;
  ros::Timer timer_;
  tf2_ros::TransformBroadcaster tf_;
  tf2_ros::StaticTransformBroadcaster static_tf_;
};

MockRobotNode::MockRobotNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

MockRobotNode::~MockRobotNode() = default;

}  // namespace ddace::nodes
