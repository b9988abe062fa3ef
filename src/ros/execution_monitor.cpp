// ExecutionMonitorNode: see include/ddace/ros/execution_monitor.h.
#include "ddace/ros/execution_monitor.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <ros/ros.h>

#include <ddace/CoordinatorState.h>
#include <ddace/DecisionRequest.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>

#include "exec_conversions.h"
#include "params.h"

namespace ddace {
namespace {

std::string stepText(const std::vector<std::string>& keys) {
  std::string s;
  for (const auto& k : keys) s += (s.empty() ? "" : " ") + k;
  return s;
}

}  // namespace
}  // namespace ddace

namespace ddace::nodes {

class ExecutionMonitorNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = ros_exec::loadTaskSpec(task_path);
    const int gt = rosparam::param(pnh, "ground_truth_demo", -1);
    if (gt >= 0) {
      std::vector<std::string> files;
      for (const auto& f : std::filesystem::directory_iterator(std::filesystem::path(task_path) / "demos"))
        if (f.path().extension() == ".csv") files.push_back(f.path().string());
      std::sort(files.begin(), files.end());
      if (gt >= static_cast<int>(files.size()))
        throw Error("parameter '" + pnh.resolveName("ground_truth_demo") + "' = " + std::to_string(gt) +
                    " is beyond the " + std::to_string(files.size()) + " demonstrations");
      gt_file_ = files[gt];
      gt_ = task::readDemonstrationCsv(gt_file_, spec_);
      have_gt_ = true;
    }
    result_file_ = rosparam::param<std::string>(pnh, "result_file", "");
    report_file_ = rosparam::param<std::string>(pnh, "report_file", "");
    const double timeout_s = rosparam::param(pnh, "timeout_s", 0.0);
    for (const auto& e : spec_.entities) {
      if (e.kind == task::EntityKind::Goal) continue;
      subs_.push_back(nh.subscribe<ddace::Segment>("/robots/" + e.name + "/segment", 20,
                                                   [this](const ddace::Segment::ConstPtr& m) { onSegment(*m); }));
      subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
          "/robots/" + e.name + "/segment_status", 50, [this](const ddace::SegmentStatus::ConstPtr& m) { onStatus(*m); }));
    }
    subs_.push_back(nh.subscribe("/ddace/decision_request", 10, &Impl::onDecisionRequest, this));
    subs_.push_back(nh.subscribe("/coordinator/state", 10, &Impl::onState, this));
    if (timeout_s > 0)
      timer_ = nh.createTimer(ros::Duration(timeout_s), [this, timeout_s](const ros::TimerEvent&) {
        ROS_ERROR("execution_monitor: the run did not end within %.0f s", timeout_s);
        report("timed out (monitor)", {});
      }, true);
  }

 private:
  // Topics from different publishers may arrive in any order, so the check compares the
  // stamps: a request stamped after a segment was sent and before it ended is a violation.
  void onSegment(const ddace::Segment& m) {
    if (m.mode != ddace::Segment::MODE_FOLLOW) return;
    Seg& seg = segments_[m.segment_id];
    seg.key = m.token.entity + ":" + m.token.action + (m.token.target.empty() ? "" : ":" + m.token.target);
    seg.sent = m.header.stamp;
  }

  void onStatus(const ddace::SegmentStatus& m) {
    if (m.status != ddace::SegmentStatus::DONE && m.status != ddace::SegmentStatus::FAILED &&
        m.status != ddace::SegmentStatus::ABORTED)
      return;
    Seg& seg = segments_[m.segment_id];
    if (seg.ended != ros::Time()) return;
    seg.ended = m.header.stamp;
  }

  void onDecisionRequest(const ddace::DecisionRequest& m) { requests_.push_back(m.header.stamp); }

  int violations() const {
    int n = 0;
    for (const auto& r : requests_)
      for (const auto& [id, seg] : segments_)
        if (seg.sent != ros::Time() && seg.sent < r && (seg.ended == ros::Time() || r < seg.ended)) {
          ROS_ERROR("execution_monitor: a decision was requested at %.3f while segment %u (%s) was running", r.toSec(),
                    id, seg.key.c_str());
          ++n;
        }
    return n;
  }

  void onState(const ddace::CoordinatorState& s) {
    if (s.state == ddace::CoordinatorState::FINISHED || s.state == ddace::CoordinatorState::ABORTED ||
        s.state == ddace::CoordinatorState::ESTOPPED)
    {
      if (final_timer_.isValid()) return;
      // Status messages of the last segments may still be on their way on other connections.
      final_timer_ = nh_.createTimer(ros::Duration(0.5), [this, s](const ros::TimerEvent&) {
        report(s.state_name + (s.reason.empty() ? "" : " (" + s.reason + ")"), s);
      }, true);
    }
  }

  void report(const std::string& outcome, const ddace::CoordinatorState& s) {
    if (reported_) return;
    reported_ = true;
    const bool finished = s.state == ddace::CoordinatorState::FINISHED;
    std::vector<std::vector<std::string>> executed, truth;
    for (const auto& step : s.steps) {
      executed.emplace_back();
      for (const auto& t : step.tokens)
        executed.back().push_back(t.entity + ":" + t.action + (t.target.empty() ? "" : ":" + t.target));
      std::sort(executed.back().begin(), executed.back().end());
    }
    if (have_gt_)
      for (const auto& step : gt_.steps) {
        truth.emplace_back();
        for (const auto& t : step.tokens) truth.back().push_back(task::tokenKey(t, spec_));
        std::sort(truth.back().begin(), truth.back().end());
      }
    std::ostringstream os;
    os << "\n=== ddace execution: task '" << spec_.name << "'";
    if (have_gt_) os << ", ground truth " << gt_file_;
    os << "\n";
    const size_t rows = std::max(executed.size(), truth.size());
    int right = 0;
    for (size_t k = 0; k < rows; ++k) {
      os << "  step " << k + 1 << ": " << (k < executed.size() ? stepText(executed[k]) : "(none)");
      if (have_gt_) {
        const bool same = k < executed.size() && k < truth.size() && executed[k] == truth[k];
        right += same && k < truth.size();
        os << (same ? "   [= ground truth]" : "   [ground truth: " + (k < truth.size() ? stepText(truth[k]) : "END") + "]");
      }
      os << "\n";
    }
    os << "  " << (finished ? "END" : "(no END)") << "\n";
    const double duration = s.steps.empty() ? 0.0 : (s.header.stamp - s.steps.front().decided).toSec();
    os << "result: " << outcome << ", " << duration << " s from the first decision to the end, " << s.decisions_requested
       << " decisions requested\n";
    int gc_met = 0;
    for (size_t i = 0; i < s.goal_conditions.size(); ++i) {
      gc_met += s.goal_conditions_met[i] ? 1 : 0;
      os << "  goal condition " << s.goal_conditions[i] << ": " << (s.goal_conditions_met[i] ? "met" : "NOT met")
         << "\n";
    }
    double ssr = 0, gcr = 0;
    int gt_motion = 0, matched = 0;
    if (have_gt_) {
      ssr = truth.empty() ? 1.0 : static_cast<double>(right) / truth.size();
      std::vector<std::string> done;  // motion tokens reported done, from the coordinator's record
      for (const auto& step : s.steps)
        for (size_t i = 0; i < step.tokens.size() && i < step.status.size(); ++i)
          if (!step.tokens[i].target.empty() && step.status[i] == ddace::SegmentStatus::DONE)
            done.push_back(step.tokens[i].entity + ":" + step.tokens[i].action + ":" + step.tokens[i].target);
      for (const auto& seg : gt_.segments) {
        if (!seg.token.isMotion() || spec_.entities[seg.token.entity].kind != task::EntityKind::Robot) continue;
        ++gt_motion;
        auto it = std::find(done.begin(), done.end(), task::tokenKey(seg.token, spec_));
        if (it != done.end()) ++matched, done.erase(it);
      }
      gcr = gt_motion ? static_cast<double>(matched) / gt_motion : 1.0;
    }
    const bool all_gc = gc_met == static_cast<int>(s.goal_conditions.size());
    const bool osr = have_gt_ && finished && right == static_cast<int>(truth.size()) &&
                     executed.size() == truth.size() && gcr == 1.0 && all_gc;
    if (have_gt_)
      os << "metrics: SSR " << ssr << " (" << right << "/" << truth.size() << " steps), GCR " << gcr << " ("
         << matched << "/" << gt_motion << " robot motion tokens done), goal conditions " << gc_met << "/"
         << s.goal_conditions.size() << ", OSR " << (osr ? 1 : 0) << "\n";
    const int violations = this->violations();
    os << "decisions requested while a segment was running: " << violations << "\n";
    std::cout << os.str() << std::flush;
    if (!report_file_.empty()) std::ofstream(report_file_) << os.str();
    if (!result_file_.empty()) {
      std::ofstream f(result_file_);
      f << "{\"task\": \"" << spec_.name << "\", \"state\": \"" << s.state_name << "\", \"steps\": " << executed.size()
        << ", \"ssr\": " << ssr << ", \"gcr\": " << gcr << ", \"goal_conditions_met\": " << gc_met
        << ", \"osr\": " << (osr ? 1 : 0) << ", \"duration_s\": " << duration
        << ", \"decisions_while_running\": " << violations << "}\n";
    }
    ros::shutdown();
  }

  task::TaskSpec spec_;
  task::Demonstration gt_;
  std::string gt_file_, result_file_, report_file_;
  bool have_gt_ = false, reported_ = false;
  struct Seg {
    std::string key;
    ros::Time sent, ended;
  };
  std::map<uint32_t, Seg> segments_;
  std::vector<ros::Time> requests_;
  std::vector<ros::Subscriber> subs_;
  ros::Timer timer_, final_timer_;
  ros::NodeHandle nh_;
};

ExecutionMonitorNode::ExecutionMonitorNode(ros::NodeHandle nh, ros::NodeHandle pnh) : impl_(std::make_unique<Impl>(nh, pnh)) {}

ExecutionMonitorNode::~ExecutionMonitorNode() = default;

}  // namespace ddace::nodes
