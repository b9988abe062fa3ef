#include "exec_conversions.h"

#include "params.h"

#include <cmath>
#include <algorithm>
#include <filesystem>
#include <type_traits>

#include <tf2/LinearMath/Quaternion.h>

#include "ddace/exec/scene.h"

namespace ddace::ros_exec {

using rosparam::param;

ddace::WheelCommand toMsg(const exec::WheelSpeeds& wheels) {
  ddace::WheelCommand m;
  m.header.stamp = ros::Time::now();
  m.left_mps = wheels.left_mps;
  m.right_mps = wheels.right_mps;
  return m;
}

uint8_t statusCode(exec::SegmentState s) {
  switch (s) {
    case exec::SegmentState::Accepted:
      return ddace::SegmentStatus::ACCEPTED;
    case exec::SegmentState::Running:
      return ddace::SegmentStatus::RUNNING;
    case exec::SegmentState::Done:
      return ddace::SegmentStatus::DONE;
    case exec::SegmentState::Failed:
      return ddace::SegmentStatus::FAILED;
    case exec::SegmentState::Aborted:
    case exec::SegmentState::Sent:
      break;
  }
  return ddace::SegmentStatus::ABORTED;
}

std::optional<exec::SegmentState> endedState(uint8_t status) {
  switch (status) {
    case ddace::SegmentStatus::DONE:
      return exec::SegmentState::Done;
    case ddace::SegmentStatus::FAILED:
      return exec::SegmentState::Failed;
    case ddace::SegmentStatus::ABORTED:
      return exec::SegmentState::Aborted;
    default:
      return std::nullopt;  // accepted, running: nothing ends
  }
}

ddace::SegmentStatus statusMsg(const std::string& entity, uint32_t segment_id, uint8_t status, double progress,
                               double distance_to_goal_m, const std::string& message) {
  ddace::SegmentStatus s;
  s.header.stamp = ros::Time::now();
  s.entity = entity;
  s.segment_id = segment_id;
  s.status = status;
  s.progress = progress;
  s.distance_to_goal_m = distance_to_goal_m;
  s.message = message;
  return s;
}

ddace::SegmentStatus statusMsg(const exec::ObjectStatus& status, const task::TaskSpec& spec) {
  return statusMsg(spec.entities.at(status.entity).name, status.segment_id, statusCode(status.state), status.progress,
                   status.distance_to_goal_m, status.message);
}

task::TaskSpec loadTaskSpec(const std::string& task_path) {
  namespace fs = std::filesystem;
  if (task_path.empty()) throw Error("no task given (parameter 'task': a task directory or its task.yaml)");
  requireAbsolute(task_path, "task");
  fs::path p(task_path);
  if (fs::is_directory(p)) p /= "task.yaml";
  if (!fs::exists(p)) throw Error(Diagnostic{p.string(), 0, 0, "task file does not exist"});
  return task::readTaskYaml(p.string());
}

void requireAbsolute(const std::string& path, const std::string& param) {
  if (!path.empty() && std::filesystem::path(path).is_relative())
    throw Error(
        "parameter '" + param + "' = '" + path +
        "' is a relative path, but nodes run in ROS_HOME, not in your working directory: give an absolute "
        "path (scripts/execute_sim and execute_sim.launch resolve relative paths against the caller's directory)");
}

task::Token fromMsg(const ddace::Token& msg, const task::TaskSpec& spec) {
  task::Token t;
  t.entity = spec.entityIndex(msg.entity);
  if (t.entity < 0) throw Error("token names an unknown entity '" + msg.entity + "'");
  if (msg.action.empty()) throw Error("token of '" + msg.entity + "' has no action");
  t.action = msg.action;
  if (!msg.target.empty()) {
    t.target = spec.entityIndex(msg.target);
    if (t.target < 0)
      throw Error("token " + msg.entity + ":" + msg.action + " names an unknown target '" + msg.target + "'");
  }
  return t;
}

std::optional<task::Token> tokenOrNothing(const ddace::Token& msg, const task::TaskSpec& spec) {
  try {
    return fromMsg(msg, spec);
  } catch (const Error&) {
    return std::nullopt;
  }
}

ddace::Token toMsg(const task::Token& token, const task::TaskSpec& spec, double probability) {
  ddace::Token m;
  m.entity = spec.entities.at(token.entity).name;
  m.action = token.action;
  if (token.target >= 0) m.target = spec.entities.at(token.target).name;
  m.probability = probability;
  return m;
}

void toMsg(const exec::PlannedPath& path, const std::string& frame_id, const ros::Time& stamp, nav_msgs::Path& out,
           std::vector<double>& progress, std::vector<double>& stddev_m) {
  out.header.frame_id = frame_id;
  out.header.stamp = stamp;
  out.poses.clear();
  const size_t n = path.points.size();
  for (size_t i = 0; i < n; ++i) {
    geometry_msgs::PoseStamped ps;
    ps.header = out.header;
    ps.pose.position.x = path.points[i].x();
    ps.pose.position.y = path.points[i].y();
    const Eigen::Vector2d d =
        n < 2 ? Eigen::Vector2d(1, 0)
              : (i + 1 < n ? path.points[i + 1] - path.points[i] : path.points[i] - path.points[i - 1]);
    tf2::Quaternion q;
    q.setRPY(0, 0, std::atan2(d.y(), d.x()));
    ps.pose.orientation.x = q.x();
    ps.pose.orientation.y = q.y();
    ps.pose.orientation.z = q.z();
    ps.pose.orientation.w = q.w();
    out.poses.push_back(ps);
  }
  progress = exec::progressOf(path.points);
  stddev_m = path.stddev_m.size() == n ? path.stddev_m : std::vector<double>(n, 0.0);
}

exec::PlannedPath fromMsg(const nav_msgs::Path& path, const std::vector<double>& stddev_m, const std::string& what) {
  exec::PlannedPath p;
  for (size_t i = 0; i < path.poses.size(); ++i) {
    const auto& pos = path.poses[i].pose.position;
    if (!std::isfinite(pos.x) || !std::isfinite(pos.y))
      throw Error(what + ": path point " + std::to_string(i) + " is not finite");
    p.points.emplace_back(pos.x, pos.y);
  }
  if (!stddev_m.empty() && stddev_m.size() != p.points.size())
    throw Error(what + ": stddev_m has " + std::to_string(stddev_m.size()) + " values for " +
                std::to_string(p.points.size()) + " path points");
  p.stddev_m = stddev_m;
  return p;
}

exec::EntityObservation toObservation(const ddace::EntityArray& msg, const task::TaskSpec& spec,
                                      std::vector<double>* yaws) {
  const size_t n = spec.entities.size();
  exec::EntityObservation obs;
  obs.positions.assign(n, Eigen::Vector2d::Zero());
  obs.tracked.assign(n, false);
  if (yaws) yaws->assign(n, 0.0);
  for (const auto& e : msg.entities) {
    const int i = spec.entityIndex(e.name);
    if (i < 0) continue;  // markers of things that are not part of this task
    const bool finite = std::isfinite(e.pose.x) && std::isfinite(e.pose.y) && std::isfinite(e.pose.theta);
    obs.positions[i] = finite ? Eigen::Vector2d(e.pose.x, e.pose.y) : Eigen::Vector2d::Zero();
    obs.tracked[i] = finite && !e.stale;
    if (yaws && finite) (*yaws)[i] = e.pose.theta;
  }
  return obs;
}

namespace {

/// `params` with every field its visitParams() lists read from the parameter of that name
/// under `nh` (a field keeps its value when the parameter is not set; a mistyped one
/// throws), once its validate() passes; an error names the parameters' namespace.
template <typename Params>
Params loadParams(const ros::NodeHandle& nh, Params params) {
  exec::visitParams(params, [&](const char* name, auto& field) {
    using T = std::decay_t<decltype(field)>;
    if constexpr (std::is_same_v<T, uint64_t>)  // ROS parameters have no unsigned type
      field = static_cast<uint64_t>(param(nh, name, static_cast<int>(field)));
    else field = param(nh, name, field);
  });
  try {
    params.validate();
  } catch (const Error& e) {
    throw Error(std::string(e.what()) + " (parameters under " + nh.getNamespace() + ")");
  }
  return params;
}

}  // namespace

exec::FollowerGains loadFollowerGains(const ros::NodeHandle& nh) {
  return loadParams(nh, exec::FollowerGains{});
}

exec::SafetyParams loadSafetyParams(const ros::NodeHandle& nh) {
  return loadParams(nh, exec::SafetyParams{});
}

exec::DiffDriveParams loadDiffDriveParams(const ros::NodeHandle& nh) {
  return loadParams(nh, exec::simulatedHamster());  // the mock robots' Hamster
}

exec::TableSimulatorParams loadTableParams(const ros::NodeHandle& nh, const exec::TableSimulatorParams& defaults) {
  return loadParams(nh, defaults);
}

}  // namespace ddace::ros_exec

namespace ddace::ros_exec {

std::vector<exec::Pose2D> loadScene(const ros::NodeHandle& pnh, const task::TaskSpec& spec,
                                    const std::string& task_path,
                                    const std::function<std::vector<exec::Pose2D>()>& fallback) {
  std::vector<exec::Pose2D> base;
  std::string csv = param<std::string>(pnh, "scene_csv", "");
  const int demo_index = param(pnh, "scene_demo", -1);
  if (csv.empty() && demo_index >= 0)
    csv = task::demoFile(task_path, demo_index, "parameter '" + pnh.resolveName("scene_demo") + "'");
  if (!csv.empty()) {
    base = exec::startPoses(task::readDemonstrationCsv(csv, spec));
    ROS_INFO("%s: scene from the first row of %s", ros::this_node::getName().c_str(), csv.c_str());
  } else if (fallback) {
    base = fallback();
  }
  std::vector<exec::NamedPose> named;
  if (auto scene = rosparam::optionalParam<XmlRpc::XmlRpcValue>(pnh, "scene")) {
    if (scene->getType() != XmlRpc::XmlRpcValue::TypeStruct)
      throw Error("parameter '" + pnh.resolveName("scene") + "' must be a map name: [x, y] or [x, y, yaw]");
    for (auto it = scene->begin(); it != scene->end(); ++it) {
      const std::string where = "parameter '" + pnh.resolveName("scene") + "/" + it->first + "'";
      auto& v = it->second;
      if (v.getType() != XmlRpc::XmlRpcValue::TypeArray || (v.size() != 2 && v.size() != 3))
        throw Error(where + " must be [x, y] or [x, y, yaw]");
      auto num = [&](int k) {
        auto& x = v[k];
        if (x.getType() == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(x);
        if (x.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<double>(static_cast<int>(x));
        throw Error(where + " element " + std::to_string(k) + " is not a number");
      };
      named.push_back({it->first, {num(0), num(1), v.size() == 3 ? num(2) : 0.0}, where});
    }
  }
  return exec::sceneStartPoses(spec, base, named,
                               "set '" + pnh.resolveName("scene_csv") + "', '" + pnh.resolveName("scene_demo") +
                                   "' or '" + pnh.resolveName("scene") + "'");
}

}  // namespace ddace::ros_exec
