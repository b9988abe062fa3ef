// GpPathNode: see include/ddace/ros/gp_path.h.
#include "ddace/ros/gp_path.h"

#include <filesystem>
#include <functional>
#include <memory>

#include <ros/ros.h>

#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>

#include "exec_conversions.h"
#include "ddace/ros/heartbeat.h"
#include "params.h"
#include "ddace/exec/replay.h"
#include "ddace/gp/primitives.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/task/fingerprint.h"

namespace ddace::nodes {

class GpPathNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    const GpPathNode::Params defaults;
    frame_id_ = rosparam::param(pnh, "frame_id", defaults.frame_id);
    default_points_ = rosparam::param(pnh, "points", defaults.points);
    if (default_points_ < 2) throw Error("parameter '" + pnh.resolveName("points") + "' must be at least 2");
    const auto source_name = rosparam::optionalParam<std::string>(pnh, "source");
    const GpPathNode::Source source =
        source_name ? GpPathNode::parseSource(*source_name, pnh.resolveName("source")) : defaults.source;
    rosparam::alsoReads(pnh, {"library", "allow_other_task"});  // source 'library' only
    if (source == GpPathNode::Source::Library) {
      std::string path = rosparam::param<std::string>(pnh, "library", "");
      if (path.empty()) throw Error("source 'library' needs parameter '" + pnh.resolveName("library") + "'");
      spec_ = ros_exec::loadTaskSpec(task_path);
      namespace fs = std::filesystem;
      if (fs::is_directory(path)) {
        // A model directory goes through the one model loader (every file verified).
        if (!fs::exists(fs::path(path) / "manifest.yaml"))
          throw Error(Diagnostic{path, 0, 0,
                                 "not a model directory (no manifest.yaml): give a model directory "
                                 "written by ddace train, or a primitives.yaml"});
        // A task of the same kinds in other numbers: the library bound to its entities.
        const bool allow_other_task = rosparam::param(pnh, "allow_other_task", defaults.allow_other_task);
        const pipeline::ModelForTask model = pipeline::modelForTask(
            pipeline::loadModel(path), path, spec_, task::fingerprintOfPath(task_path), task_path, allow_other_task,
            "set parameter '" + pnh.resolveName("allow_other_task") + "' to true");
        if (!model.model.primitives)
          throw Error(
              Diagnostic{path, 0, 0, "a " + model.model.sequence.variant() + " model has no primitive library"});
        library_ = std::make_unique<gp::PrimitiveLibrary>(*model.model.primitives);
        if (!model.note.empty()) ROS_INFO("gp_path: %s", model.note.c_str());
      } else {
        library_ = std::make_unique<gp::PrimitiveLibrary>(gp::PrimitiveLibrary::load(path));
        if (!rosparam::param(pnh, "allow_other_task", defaults.allow_other_task))
          task::requireSameTask(library_->taskFingerprint(), path + " (task '" + library_->taskName() + "')",
                                task::fingerprintOfPath(task_path), task_path + " (task '" + spec_.name + "')",
                                "set parameter '" + pnh.resolveName("allow_other_task") + "' to true");
      }
      if (rosparam::param(pnh, "allow_other_task", defaults.allow_other_task))
        ROS_WARN("gp_path: %s: the library's task is not checked against %s",
                 pnh.resolveName("allow_other_task").c_str(), task_path.c_str());
      generate_ = [this](const task::Token& t, const Eigen::Vector2d& s, const Eigen::Vector2d& g, int step) {
        // The library's own entity indices: map by key; the step chooses a role's primitive.
        const gp::GeneratedPath p = library_->generate(task::tokenKey(t, spec_), s, g, points_, step);
        if (p.fell_back)
          ROS_WARN("gp_path: %s was never demonstrated; using %s", task::tokenKey(t, spec_).c_str(),
                   p.source_key.c_str());
        fell_back_ = p.fell_back;
        return exec::PlannedPath{p.points, p.stddev};
      };
      ROS_INFO("gp_path: primitive library %s", path.c_str());
    } else {
      const task::TaskDir dir = task::loadTaskDir(task_path);
      spec_ = dir.spec;
      demo_paths_ = std::make_unique<exec::DemonstrationPaths>(dir.spec, dir.demos);
      generate_ = [this](const task::Token& t, const Eigen::Vector2d& s, const Eigen::Vector2d& g, int) {
        return demo_paths_->generate(t, s, g);
      };
      ROS_INFO("gp_path: %zu demonstrated motion keys from %s", demo_paths_->size(), task_path.c_str());
    }
    pub_ = nh.advertise<ddace::PathResponse>("/ddace/path", 50);
    sub_ = nh.subscribe("/ddace/path_request", 50, &Impl::onRequest, this);
    heartbeat_ = std::make_unique<HeartbeatPublisher>(pnh);  // the coordinator watches it
  }

 private:
  void onRequest(const ddace::PathRequest& req) {
    ddace::PathResponse out;
    out.header.stamp = ros::Time::now();
    out.header.frame_id = frame_id_;
    out.id = req.id;
    try {
      const task::Token token = ros_exec::fromMsg(req.token, spec_);
      if (!token.isMotion()) throw Error("token " + task::tokenKey(token, spec_) + " is not a motion (no target)");
      const Eigen::Vector2d start(req.start.x, req.start.y), goal(req.goal.x, req.goal.y);
      if (!start.allFinite() || !goal.allFinite()) throw Error("start or goal is not finite");
      points_ = req.points >= 2 ? req.points : default_points_;
      fell_back_ = false;
      const exec::PlannedPath p = exec::resampleByArcLength(generate_(token, start, goal, req.step), points_);
      out.fell_back = fell_back_;
      ros_exec::toMsg(p, frame_id_, out.header.stamp, out.path, out.progress, out.stddev_m);
    } catch (const std::exception& e) {
      out.error = e.what();
      ROS_ERROR("gp_path: path request %u refused: %s", req.id, e.what());
    }
    pub_.publish(out);
  }

  task::TaskSpec spec_;
  std::string frame_id_;
  int default_points_ = 0;  // set from the parameters
  std::unique_ptr<exec::DemonstrationPaths> demo_paths_;
  std::unique_ptr<gp::PrimitiveLibrary> library_;
  int points_ = 0;  // of the request being answered
  bool fell_back_ = false;
  std::function<exec::PlannedPath(const task::Token&, const Eigen::Vector2d&, const Eigen::Vector2d&, int step)>
      generate_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
  std::unique_ptr<HeartbeatPublisher> heartbeat_;
};

GpPathNode::Source GpPathNode::parseSource(const std::string& value, const std::string& param_name) {
  if (value == "library") return Source::Library;
  if (value == "demonstration") return Source::Demonstration;
  throw Error("parameter '" + param_name + "' = '" + value + "': expected 'library' or 'demonstration'");
}

GpPathNode::GpPathNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

GpPathNode::~GpPathNode() = default;

}  // namespace ddace::nodes
