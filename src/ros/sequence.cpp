// SequenceNode: see include/ddace/ros/sequence.h.
#include "ddace/ros/sequence.h"
#include "ddace/task/task_dir.h"

#include <algorithm>
#include <filesystem>
#include <functional>
#include <memory>

#include <ros/ros.h>

#include <ddace/Decision.h>
#include <ddace/DecisionRequest.h>

#include "exec_conversions.h"
#include "ddace/ros/heartbeat.h"
#include "params.h"
#include "ddace/exec/replay.h"
#include "ddace/pipeline/decisions_without.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/task/fingerprint.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::nodes {

class SequenceNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = ros_exec::loadTaskSpec(task_path);
    const SequenceNode::Params defaults;
    const auto policy_name = rosparam::optionalParam<std::string>(pnh, "policy");
    const SequenceNode::Policy policy =
        policy_name ? SequenceNode::parsePolicy(*policy_name, pnh.resolveName("policy")) : defaults.policy;
    // Each policy's own parameters; the other's are known too (config/execution.yaml sets both).
    rosparam::alsoReads(pnh, {"model", "allow_other_task", "replay_csv", "replay_demo"});
    if (policy == SequenceNode::Policy::Model) {
      const std::string dir = rosparam::param<std::string>(pnh, "model", "");
      if (dir.empty())
        throw Error("policy 'model' needs parameter '" + pnh.resolveName("model") + "' (a model directory)");
      ros_exec::requireAbsolute(dir, pnh.resolveName("model"));
      // The one model loader: every file of the directory is verified, primitives.yaml too.
      // A task of the same kinds in other numbers runs the model bound to its entities.
      const bool allow_other_task = rosparam::param(pnh, "allow_other_task", defaults.allow_other_task);
      if (allow_other_task)
        ROS_WARN("sequence: %s: the model's task is not checked against %s",
                 pnh.resolveName("allow_other_task").c_str(), task_path.c_str());
      const pipeline::ModelForTask bound = pipeline::modelForTask(
          pipeline::loadModel(dir), dir, spec_, task::fingerprintOfPath(task_path), task_path, allow_other_task,
          "set parameter '" + pnh.resolveName("allow_other_task") + "' to true");
      if (!bound.note.empty()) ROS_INFO("sequence: %s", bound.note.c_str());
      model_ = std::make_unique<tgn::SequenceModel>(bound.model.sequence);
      without_ = std::make_unique<pipeline::DecisionsWithout>(*model_);
      policy_ = [this](const std::vector<task::Snapshot>& h, const std::vector<int>& lost) {
        const tgn::Prediction p = without_->predict(h, lost);
        exec::Decision d;
        d.end = p.end;
        d.tokens = p.tokens;
        last_probabilities_ = p.token_probabilities;
        last_end_probability_ = p.end_probability;
        return d;
      };
      ROS_INFO("sequence: model %s (variant %s)", dir.c_str(), model_->variant().c_str());
    } else {
      std::string csv = rosparam::param<std::string>(pnh, "replay_csv", "");
      if (csv.empty())
        csv = task::demoFile(task_path, rosparam::param(pnh, "replay_demo", defaults.replay_demo),
                             "parameter '" + pnh.resolveName("replay_demo") + "'");
      demo_ = task::readDemonstrationCsv(csv, spec_);
      policy_ = [this](const std::vector<task::Snapshot>& h, const std::vector<int>& lost) {
        if (!lost.empty())
          throw Error("a replay decides the demonstrated steps: it cannot decide without " +
                      spec_.entities[static_cast<size_t>(lost.front())].name);
        return exec::replayDecision(demo_, h);
      };
      ROS_INFO("sequence: replaying the %zu steps of %s", demo_.steps.size(), csv.c_str());
    }
    pub_ = nh.advertise<ddace::Decision>("/ddace/decision", 5);
    sub_ = nh.subscribe("/ddace/decision_request", 5, &Impl::onRequest, this);
    heartbeat_ = std::make_unique<HeartbeatPublisher>(pnh);  // the coordinator watches it
  }

 private:
  void onRequest(const ddace::DecisionRequest& req) {
    ddace::Decision out;
    out.header.stamp = ros::Time::now();
    out.id = req.id;
    try {
      // Map the request's entity order onto the task's.
      const size_t n = spec_.entities.size();
      std::vector<int> index(req.entity_names.size(), -1);
      std::vector<bool> seen(n, false);
      for (size_t k = 0; k < req.entity_names.size(); ++k) {
        index[k] = spec_.entityIndex(req.entity_names[k]);
        if (index[k] < 0) throw Error("request names entity '" + req.entity_names[k] + "', not in the task");
        seen[index[k]] = true;
      }
      for (size_t i = 0; i < n; ++i)
        if (!seen[i]) throw Error("request has no position of entity '" + spec_.entities[i].name + "'");
      std::vector<task::Snapshot> history;
      for (size_t s = 0; s < req.history.size(); ++s) {
        const auto& snap = req.history[s];
        if (snap.positions.size() != req.entity_names.size())
          throw Error("snapshot " + std::to_string(s) + " has " + std::to_string(snap.positions.size()) +
                      " positions for " + std::to_string(req.entity_names.size()) + " entities");
        task::Snapshot t;
        t.row = static_cast<int>(s);
        t.positions.assign(n, Eigen::Vector2d::Zero());
        for (size_t k = 0; k < snap.positions.size(); ++k) {
          if (!std::isfinite(snap.positions[k].x) || !std::isfinite(snap.positions[k].y))
            throw Error("snapshot " + std::to_string(s) + ": position of " + req.entity_names[k] + " is not finite");
          t.positions[index[k]] = {snap.positions[k].x, snap.positions[k].y};
        }
        history.push_back(std::move(t));
      }
      if (history.empty()) throw Error("request has an empty snapshot history");
      std::vector<int> lost;
      for (const std::string& name : req.lost) {
        const int e = spec_.entityIndex(name);
        if (e < 0) throw Error("request names lost entity '" + name + "', not in the task");
        lost.push_back(e);
      }
      last_probabilities_.clear();
      last_end_probability_ = -1;
      const exec::Decision d = policy_(history, lost);
      out.end = d.end;
      out.end_probability = last_end_probability_ >= 0 ? last_end_probability_ : (d.end ? 1.0 : 0.0);
      for (size_t i = 0; i < d.tokens.size(); ++i)
        out.tokens.push_back(
            ros_exec::toMsg(d.tokens[i], spec_, i < last_probabilities_.size() ? last_probabilities_[i] : 1.0));
      std::string line;
      for (const auto& t : d.tokens) line += " " + task::tokenKey(t, spec_);
      ROS_INFO("sequence: decision %u (step %d):%s", req.id, req.step + 1, d.end ? " END" : line.c_str());
    } catch (const std::exception& e) {
      out.error = e.what();
      out.tokens.clear();
      ROS_ERROR("sequence: decision request %u refused: %s", req.id, e.what());
    }
    pub_.publish(out);
  }

  task::TaskSpec spec_;
  task::Demonstration demo_;
  std::unique_ptr<tgn::SequenceModel> model_;
  std::unique_ptr<pipeline::DecisionsWithout> without_;  ///< model_ for the team without lost robots
  std::vector<double> last_probabilities_;
  double last_end_probability_ = -1;
  /// The next step from the history, for the team without the lost robots (task indices).
  std::function<exec::Decision(const std::vector<task::Snapshot>&, const std::vector<int>&)> policy_;
  ros::Publisher pub_;
  ros::Subscriber sub_;
  std::unique_ptr<HeartbeatPublisher> heartbeat_;
};

SequenceNode::Policy SequenceNode::parsePolicy(const std::string& value, const std::string& param_name) {
  if (value == "model") return Policy::Model;
  if (value == "replay") return Policy::Replay;
  throw Error("parameter '" + param_name + "' = '" + value + "': expected 'model' or 'replay'");
}

SequenceNode::SequenceNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

SequenceNode::~SequenceNode() = default;

}  // namespace ddace::nodes
