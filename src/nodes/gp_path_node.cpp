// gp_path_node: answers path requests (token key, start, goal) with a progress-
// parameterised path and its per-point standard deviation.
//
//   in  /ddace/path_request (PathRequest)
//   out /ddace/path (PathResponse)
//
// Path sources (parameter `source`):
//   demonstration  the first demonstrated trajectory of the token's key in `task`'s demos/,
//                  retargeted to the new start and goal by a similarity transform; zero
//                  standard deviation (one demonstration has no spread).
// Parameters: config/execution.yaml, section gp_path.
#include <memory>

#include <ros/ros.h>

#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>

#include "../ros/exec_conversions.h"
#include "ddace/exec/replay.h"

namespace ddace {
namespace {

class GpPathNode {
 public:
  GpPathNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const std::string task_path = ros_exec::param<std::string>(pnh, "task", "");
    frame_id_ = ros_exec::param<std::string>(pnh, "frame_id", "table");
    default_points_ = ros_exec::param(pnh, "points", 100);
    if (default_points_ < 2) throw Error("parameter '" + pnh.resolveName("points") + "' must be at least 2");
    const std::string source = ros_exec::param<std::string>(pnh, "source", "demonstration");
    if (source == "demonstration") {
      const task::TaskDir dir = task::loadTaskDir(task_path);
      spec_ = dir.spec;
      demo_paths_ = std::make_unique<exec::DemonstrationPaths>(dir.spec, dir.demos);
      generate_ = [this](const task::Token& t, const Eigen::Vector2d& s, const Eigen::Vector2d& g) {
        return demo_paths_->generate(t, s, g);
      };
      ROS_INFO("gp_path: %zu demonstrated motion keys from %s", demo_paths_->size(), task_path.c_str());
    } else {
      throw Error("parameter '" + pnh.resolveName("source") + "' = '" + source + "': expected 'demonstration'");
    }
    pub_ = nh.advertise<ddace::PathResponse>("/ddace/path", 50);
    sub_ = nh.subscribe("/ddace/path_request", 50, &GpPathNode::onRequest, this);
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
      const exec::PlannedPath p =
          exec::resampleByArcLength(generate_(token, start, goal), req.points >= 2 ? req.points : default_points_);
      ros_exec::toMsg(p, frame_id_, out.header.stamp, out.path, out.progress, out.stddev_m);
    } catch (const std::exception& e) {
      out.error = e.what();
      ROS_ERROR("gp_path: path request %u refused: %s", req.id, e.what());
    }
    pub_.publish(out);
  }

  task::TaskSpec spec_;
  std::string frame_id_;
  int default_points_ = 100;
  std::unique_ptr<exec::DemonstrationPaths> demo_paths_;
  std::function<exec::PlannedPath(const task::Token&, const Eigen::Vector2d&, const Eigen::Vector2d&)> generate_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
};

}  // namespace
}  // namespace ddace

int main(int argc, char** argv) {
  ros::init(argc, argv, "gp_path");
  ros::NodeHandle nh, pnh("~");
  try {
    ddace::GpPathNode node(nh, pnh);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("gp_path: %s", e.what());
    return 1;
  }
  return 0;
}
