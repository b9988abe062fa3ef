// ExecutionMonitorNode: see include/ddace/ros/execution_monitor.h.
#include "ddace/ros/execution_monitor.h"
#include "ddace/common/machine.h"
#include "ddace/task/task_dir.h"

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>
#include <ros/network.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <ddace/CoordinatorState.h>
#include <ddace/DecisionRequest.h>
#include <ddace/EntityArray.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>

#include "exec_conversions.h"
#include "ddace/exec/clearance.h"
#include "ddace/exec/safety_filter.h"
#include "ddace/ros/heartbeat.h"
#include "params.h"
#include "ddace/common/file.h"
#include "ddace/eval/metrics.h"

namespace ddace::nodes {
namespace fs = std::filesystem;

namespace {

std::string stepText(const std::vector<std::string>& keys) {
  std::string s;
  for (const auto& k : keys) s += (s.empty() ? "" : " ") + k;
  return s;
}

std::string keyOf(const ddace::Token& t) {
  return t.entity + ":" + t.action + (t.target.empty() ? "" : ":" + t.target);
}

/// True when process `pid` runs roslaunch (only then is it ours to end).
bool isRoslaunch(pid_t pid) {
  try {
    return readTextFile("/proc/" + std::to_string(pid) + "/cmdline").find("roslaunch") != std::string::npos;
  } catch (const Error&) {
    return false;  // gone, or not ours to read
  }
}

/// scripts/plot_run.py as the build installs it: next to this executable (devel/lib/ddace
/// and install/lib/ddace alike), so no source tree is needed.
std::string installedPlotScript() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? "plot_run.py" : (exe.parent_path() / "plot_run.py").string();
}

using TopicNodes = std::map<std::string, std::set<std::string>>;  ///< topic -> node names

/// The master's publishers and subscribers of every topic; false when it does not answer.
bool systemState(TopicNodes& publishers, TopicNodes& subscribers) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return false;
  auto read = [](XmlRpc::XmlRpcValue& list, TopicNodes& out) {
    for (int i = 0; i < list.size(); ++i)
      for (int k = 0; k < list[i][1].size(); ++k) out[std::string(list[i][0])].insert(std::string(list[i][1][k]));
  };
  read(payload[0], publishers);
  read(payload[1], subscribers);
  return true;
}

/// How long a node may take to answer getBusInfo (seconds): a live node answers in
/// milliseconds; well under the heartbeat time-out (config/execution.yaml, 1 s).
constexpr double kBusInfoTimeoutS = 0.2;

/// (topic, subscriber node) of every outbound link of `node`, from its own getBusInfo: a
/// publisher lists a subscriber only once the handshake is done, so from then on every
/// message it publishes on that topic reaches it. False when the node does not answer.
bool outboundLinks(const std::string& node, std::set<std::pair<std::string, std::string>>& links) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return false;
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(std::string(payload), host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue a, r;
  a[0] = ros::this_node::getName();
  // Not execute(): it waits for ever, and a hung node (stopped, deadlocked) never answers;
  // this node's heartbeat would stop with it, and the coordinator would abort the run for
  // a lost recorder instead of the hung node. A node that does not answer within
  // kBusInfoTimeoutS is taken as not linked (for now: the check runs again).
  if (!client.executeNonBlock("getBusInfo", a)) return false;
  client._disp.work(kBusInfoTimeoutS);
  const bool answered = client.executeCheckDone(r);
  client.close();
  if (!answered || r.getType() != XmlRpc::XmlRpcValue::TypeArray || r.size() < 3) return false;
  XmlRpc::XmlRpcValue& info = r[2];
  for (int i = 0; i < info.size(); ++i)
    if (info[i].size() >= 5 && std::string(info[i][2]) == "o")
      links.insert({std::string(info[i][4]), std::string(info[i][1])});
  return true;
}

}  // namespace

class ExecutionMonitorNode::Impl {
 public:
  Impl(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh) {
    const std::string task_path = rosparam::param<std::string>(pnh, "task", "");
    spec_ = ros_exec::loadTaskSpec(task_path);
    const ExecutionMonitorNode::Params defaults;
    std::vector<double> radii;
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const exec::BodyShape b = exec::bodyShape(spec_, static_cast<int>(i));
      radii.push_back(b.obstacle ? b.radius_m : 0.0);
    }
    const double overlap_m = rosparam::param(pnh, "collision_overlap_m", defaults.collision_overlap_m);
    if (!(overlap_m >= 0)) throw Error("parameter '" + pnh.resolveName("collision_overlap_m") + "' must be >= 0");
    clearance_ = std::make_unique<exec::ClearanceMeter>(radii, overlap_m);
    radii_ = radii;
    // One setting, the path followers' own margin: the contacts their filters let happen
    // are the ones the report leaves out.
    contacts_ = std::make_unique<exec::StepContacts>(
        spec_, radii_, ros_exec::loadSafetyParams(ros::NodeHandle(nh, "path_follower/safety")).endsAgainstReachM());
    collisions_fail_ = rosparam::param(pnh, "collisions_fail", defaults.collisions_fail);
    at_.assign(spec_.entities.size(), Eigen::Vector2d::Constant(NAN));
    const int gt = rosparam::param(pnh, "ground_truth_demo", defaults.ground_truth_demo);
    if (gt >= 0) {
      gt_file_ = task::demoFile(task_path, gt, "parameter '" + pnh.resolveName("ground_truth_demo") + "'");
      gt_ = task::readDemonstrationCsv(gt_file_, spec_);
      have_gt_ = true;
    }
    rosparam::alsoReads(pnh, {"runs_dir"});  // read only without ~run_dir
    std::string run_dir = rosparam::param<std::string>(pnh, "run_dir", "");
    if (run_dir.empty()) {
      const char* home = std::getenv("HOME");
      std::string base =
          rosparam::param<std::string>(pnh, "runs_dir", std::string(home ? home : "/tmp") + "/.ros/ddace/runs");
      run_dir = (fs::path(base) / utcNow("%Y%m%dT%H%M%SZ")).string();
      latest_link_ = (fs::path(base) / "latest").string();
    }
    if (fs::path(run_dir).is_relative())
      throw Error("parameter '" + pnh.resolveName("run_dir") + "' = '" + run_dir +
                  "' is relative: nodes run in ROS_HOME, give an absolute path");
    std::error_code ec;
    fs::create_directories(run_dir, ec);
    if (ec) throw Error("cannot create the run directory " + run_dir + ": " + ec.message());
    run_dir_ = run_dir;
    if (!latest_link_.empty()) {
      fs::remove(latest_link_, ec);
      fs::create_directory_symlink(fs::path(run_dir_).filename(), latest_link_, ec);
    }
    plot_script_ = rosparam::param<std::string>(pnh, "plot_script", installedPlotScript());
    if (!plot_script_.empty() && fs::path(plot_script_).is_relative())
      throw Error("parameter '" + pnh.resolveName("plot_script") + "' = '" + plot_script_ +
                  "' is relative: nodes run in ROS_HOME, give an absolute path");
    end_launch_ = rosparam::param(pnh, "end_launch", defaults.end_launch);
    const double timeout_s = rosparam::param(pnh, "timeout_s", defaults.timeout_s);
    std::vector<std::string> topics = {"/ddace/entities", "/ddace/decision_request", "/coordinator/state",
                                       "/ddace/estop"};
    for (const auto& e : spec_.entities) {
      if (e.kind == task::EntityKind::Goal) continue;
      const std::string r = "/robots/" + e.name;
      topics.insert(topics.end(), {r + "/segment", r + "/segment_status"});
      if (e.kind == task::EntityKind::Robot) topics.push_back(r + "/wheels");
      subs_.push_back(nh.subscribe<ddace::Segment>(r + "/segment", 20,
                                                   [this](const ddace::Segment::ConstPtr& m) { onSegment(*m); }));
      subs_.push_back(nh.subscribe<ddace::SegmentStatus>(
          r + "/segment_status", 50, [this](const ddace::SegmentStatus::ConstPtr& m) { onStatus(*m); }));
    }
    subs_.push_back(nh.subscribe("/ddace/decision_request", 10, &Impl::onDecisionRequest, this));
    subs_.push_back(nh.subscribe("/coordinator/state", 10, &Impl::onState, this));
    subs_.push_back(nh.subscribe("/ddace/entities", 10, &Impl::onEntities, this));
    for (const auto& sub : subs_) listeners_[ros::this_node::getName()].push_back(sub.getTopic());
    record_bag_ = rosparam::param(pnh, "record_bag", defaults.record_bag);
    if (record_bag_) {
      startBag(topics);
      listeners_[bagNode()] = topics;
    }
    ready_srv_ = pnh.advertiseService("ready", &Impl::srvReady, this);
    // The links are watched all along, so that ~ready already knows the poses that came
    // since they were up (one call alone would always find none).
    link_timer_ = nh.createWallTimer(ros::WallDuration(0.2), [this](const ros::WallTimerEvent&) { notRecording(); });
    // The coordinator treats this node as the recorder role: a run without its record stops.
    heartbeat_ = std::make_unique<HeartbeatPublisher>(pnh, [this] { return bagProblem(); });
    if (timeout_s > 0)
      timer_ = nh.createTimer(
          ros::Duration(timeout_s),
          [this, timeout_s](const ros::TimerEvent&) {
            ROS_ERROR("execution_monitor: the run did not end within %.0f s", timeout_s);
            report("timed out (monitor, timeout_s = " + std::to_string(timeout_s) + ")", last_state_, "timed_out");
          },
          true);
    ROS_INFO("execution_monitor: recording the run into %s", run_dir_.c_str());
  }

  ~Impl() {
    // SIGINT (roslaunch shutting down, Ctrl-C): whatever ran is recorded as interrupted.
    if (!reported_)
      report("interrupted (SIGINT) " +
                 (have_state_ ? "in state " + last_state_.state_name : "before the coordinator reported any state"),
             last_state_, "interrupted");
    stopBag();
  }

 private:
  struct Seg {
    std::string key, entity;
    int step = 0;
    ros::Time sent, ended;
    uint8_t end_status = 0;
    std::vector<Eigen::Vector2d> planned, executed;
    std::vector<double> stddev_m;
    Eigen::Vector2d goal{0, 0};
  };

  /// "execution_monitor_bag" for /ns/execution_monitor (a node name has no slash).
  static std::string bagNodeName() {
    const std::string n = ros::this_node::getName();
    return n.substr(n.rfind('/') + 1) + "_bag";
  }
  /// The recorder's full node name (rosbag runs in this node's namespace).
  static std::string bagNode() {
    const std::string n = ros::this_node::getName();
    return n.substr(0, n.rfind('/') + 1) + bagNodeName();
  }

  /// ~ready: succeeds once the bag recorder and this node's own subscriptions are linked
  /// to every publisher the master lists for each of their topics, and /ddace/entities
  /// messages published after that have arrived; the coordinator starts a new run only then
  /// (roles/recorder), so the record holds the table at the start and the run from its
  /// first message. Otherwise the message names what is still missing.
  bool srvReady(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
    res.message = notRecording();
    res.success = res.message.empty();
    if (res.success) res.message = "recording into " + run_dir_;
    return true;
  }

  /// Why the bag cannot hold the run ("" while rosbag record runs, or no bag is wanted).
  std::string bagProblem() {
    if (reported_) return "";  // the run's record is written; the bag was stopped on purpose
    int status = 0;
    if (bag_pid_ > 0 && ::waitpid(bag_pid_, &status, WNOHANG) == bag_pid_) {
      bag_pid_ = -1;
      bag_failed_ = true;
      bag_exit_ = WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status))
                                      : "exit status " + std::to_string(WEXITSTATUS(status));
      ROS_ERROR("execution_monitor: rosbag record exited (%s): the run's bag is incomplete", bag_exit_.c_str());
    }
    return bag_failed_ ? "rosbag record exited (" + bag_exit_ + "): the run's bag is incomplete" : "";
  }

  std::string notRecording() {
    if (const std::string bag = bagProblem(); !bag.empty())
      return bag + "; no bag can be recorded (is Debian's rosbag installed?)";
    if (const std::string link = missingLink(); !link.empty()) {
      poses_since_linked_ = -1;
      return link;
    }
    // A link says that later messages arrive, not that one has: the record begins with the
    // table as it was only once a pose published after every link was up has come (a
    // publisher sends each message to all of its linked subscribers at once, so the
    // recorder has it too). The first one received after the links were seen may have been
    // on its way before; the second was published after it, so after the links. Counted on
    // arrival, not by stamps: the tracker stamps with its camera's clock.
    if (poses_since_linked_ < 0) poses_since_linked_ = 0;
    if (poses_since_linked_ < 2)
      return "waiting for /ddace/entities messages published after every link (the record begins with the table "
             "at the start)";
    return "";
  }

  /// The first link still missing between a recorded topic's publishers and this node or the
  /// recorder ("" when all are up).
  std::string missingLink() {
    TopicNodes publishers, subscribers;
    if (!systemState(publishers, subscribers)) return "the ROS master does not answer getSystemState";
    std::map<std::string, std::set<std::pair<std::string, std::string>>> links;  // publisher node -> its links
    for (const auto& [listener, topics] : listeners_) {
      for (const auto& topic : topics) {
        if (!subscribers[topic].count(listener)) return listener + " is not subscribed to " + topic + " yet";
        for (const auto& pub : publishers[topic]) {
          if (pub == listener) continue;
          if (!links.count(pub) && !outboundLinks(pub, links[pub]))
            return pub + " (publishing " + topic + ") does not answer getBusInfo";
          if (!links[pub].count({topic, listener}))
            return listener + " is not yet connected to " + pub + " on " + topic;
        }
      }
    }
    return "";
  }

  void startBag(const std::vector<std::string>& topics) {
    std::vector<std::string> args = {
        "rosbag", "record", "--quiet", "-O", run_dir_ + "/run.bag", "__name:=" + bagNodeName()};
    args.insert(args.end(), topics.begin(), topics.end());
    const pid_t monitor = ::getpid();
    bag_pid_ = ::fork();
    if (bag_pid_ == 0) {
      // When this node dies (SIGKILL too) the recorder gets SIGINT and closes the bag:
      // the run's bag then holds it up to this node's death.
      ::prctl(PR_SET_PDEATHSIG, SIGINT);
      if (::getppid() != monitor) ::_exit(1);  // it died before the line above
      // None of this node's sockets: a copy held open by the recorder would keep this node's
      // links up after it died, and the coordinator would learn of the death only when the
      // recorder, too, has exited.
      ::close_range(3, ~0U, 0);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execvp("rosbag", argv.data());
      std::cerr << "execution_monitor: cannot run rosbag (install Debian's rosbag)\n";
      ::_exit(127);
    }
    if (bag_pid_ < 0) {
      ROS_ERROR("execution_monitor: cannot start rosbag record: %s", std::strerror(errno));
      bag_failed_ = true;
      bag_exit_ = std::string("fork failed: ") + std::strerror(errno);
    }
  }

  /// Stops the recorder and waits (up to 10 s) until the bag is closed. `rosbag record` is
  /// a Python wrapper that forwards SIGINT to the recorder and exits at once, so its exit
  /// does not mean the bag is written: that is when run.bag.active has become run.bag.
  void stopBag() {
    if (bag_pid_ <= 0) return;
    ::kill(bag_pid_, SIGINT);
    const std::string active = run_dir_ + "/run.bag.active";
    bool exited = false;
    for (int i = 0; i < 100; ++i) {
      if (!exited && ::waitpid(bag_pid_, nullptr, WNOHANG) == bag_pid_) exited = true;
      if (exited && !fs::exists(active)) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (!exited) {
      ::kill(bag_pid_, SIGKILL);
      ::waitpid(bag_pid_, nullptr, 0);
    }
    if (fs::exists(active)) ROS_ERROR("execution_monitor: rosbag record did not close %s within 10 s", active.c_str());
    bag_pid_ = -1;
  }

  void onEntities(const ddace::EntityArray& m) {
    if (poses_since_linked_ >= 0 && poses_since_linked_ < 2) ++poses_since_linked_;
    for (const auto& e : m.entities) {
      if (!std::isfinite(e.pose.x) || !std::isfinite(e.pose.y)) continue;
      const Eigen::Vector2d p(e.pose.x, e.pose.y);
      positions_[e.name] = p;
      const int i = spec_.entityIndex(e.name);
      if (i >= 0) {
        at_[i] = p;
        if (!starts_.count(e.name)) starts_[e.name] = p;
      }
      auto it = running_.find(e.name);
      if (it != running_.end()) {
        auto& trace = segments_[it->second].executed;
        if (trace.empty() || (trace.back() - p).norm() > 0.002) trace.push_back(p);
      }
    }
    const size_t before = clearance_->collisions().size();
    clearance_->update(m.header.stamp.toSec(), at_, contacts_->allowed());
    for (size_t k = before; k < clearance_->collisions().size(); ++k) {
      const auto& c = clearance_->collisions()[k];
      ROS_WARN("execution_monitor: collision: %s and %s overlap", spec_.entities[c.a].name.c_str(),
               spec_.entities[c.b].name.c_str());
    }
  }

  std::string nameOf(int i) const { return i >= 0 ? spec_.entities.at(i).name : std::string("none"); }

  // Topics from different publishers may arrive in any order, so the check compares the
  // stamps: a request stamped after a segment was sent and before it ended is a violation.
  void onSegment(const ddace::Segment& m) {
    if (m.mode != ddace::Segment::MODE_FOLLOW) return;
    Seg& seg = segments_[m.segment_id];
    if (seg.sent != ros::Time()) return;  // a re-sent copy
    seg.key = keyOf(m.token);
    seg.entity = m.entity;
    seg.step = m.step;
    seg.sent = m.header.stamp;
    seg.goal = {m.goal.x, m.goal.y};
    for (const auto& p : m.path.poses) seg.planned.emplace_back(p.pose.position.x, p.pose.position.y);
    seg.stddev_m = m.stddev_m;
    noteStepSegment(m);
    auto pos = positions_.find(m.entity);
    if (pos != positions_.end()) seg.executed.push_back(pos->second);
    running_[m.entity] = m.segment_id;
  }

  /// The running step's motions, as their segments arrive (one by one, within
  /// milliseconds): who may touch whom (exec::AllowedContacts, the rule `ddace eval` uses),
  /// from the segments' end points and where the other bodies stand.
  void noteStepSegment(const ddace::Segment& m) {
    contacts_->beginStep(m.step);
    const int i = spec_.entityIndex(m.entity);
    if (i < 0 || m.path.poses.empty()) return;
    try {
      const task::Token token = ros_exec::fromMsg(m.token, spec_);
      const auto& last = m.path.poses.back().pose.position;
      contacts_->note(m.step, i, token, Eigen::Vector2d(last.x, last.y), at_);
    } catch (const std::exception& e) {
      ROS_WARN("execution_monitor: step %d, segment %u of %s: %s", m.step + 1, m.segment_id, m.entity.c_str(),
               e.what());
    }
  }

  void onStatus(const ddace::SegmentStatus& m) {
    if (m.status != ddace::SegmentStatus::DONE && m.status != ddace::SegmentStatus::FAILED &&
        m.status != ddace::SegmentStatus::ABORTED)
      return;
    auto it = segments_.find(m.segment_id);
    if (it == segments_.end() || it->second.ended != ros::Time() || it->second.entity != m.entity) return;
    it->second.ended = m.header.stamp;
    it->second.end_status = m.status;
  }

  void onDecisionRequest(const ddace::DecisionRequest& m) {
    if (request_ids_.insert(m.id).second) requests_.push_back(m.header.stamp);
  }

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
    last_state_ = s;
    have_state_ = true;
    // ~reset: the record is of the run that ends, not of the one reset before it (its
    // segments would count as motions that never arrived). Stamps, not arrival order: the
    // next run's first segments may come on their own connections before this state.
    if (s.state == ddace::CoordinatorState::IDLE && s.steps.empty()) {
      for (auto it = segments_.begin(); it != segments_.end();)
        it = it->second.sent != ros::Time() && it->second.sent < s.header.stamp ? segments_.erase(it) : std::next(it);
      for (auto it = running_.begin(); it != running_.end();)
        it = segments_.count(it->second) ? std::next(it) : running_.erase(it);
      requests_.erase(
          std::remove_if(requests_.begin(), requests_.end(), [&](const ros::Time& t) { return t < s.header.stamp; }),
          requests_.end());
    }
    if (s.state == ddace::CoordinatorState::FINISHED || s.state == ddace::CoordinatorState::ABORTED ||
        s.state == ddace::CoordinatorState::ESTOPPED) {
      if (final_timer_.isValid()) return;
      // Status messages of the last segments may still be on their way on other connections.
      final_timer_ = nh_.createTimer(
          ros::Duration(0.5),
          [this, s](const ros::TimerEvent&) {
            report(s.state_name + (s.reason.empty() ? "" : " (" + s.reason + ")"), last_state_);
          },
          true);
    }
  }

  /// The run as the closed-loop simulator would have recorded it, for eval::scoreTrial.
  exec::Trial trial(const ddace::CoordinatorState& s) const {
    exec::Trial t;
    t.ended = s.state == ddace::CoordinatorState::FINISHED;
    for (const auto& step : s.steps) {
      task::Step st;
      for (const auto& tok : step.tokens) {
        try {
          st.tokens.push_back(ros_exec::fromMsg(tok, spec_));
        } catch (const Error& e) {
          ROS_WARN("execution_monitor: step %d: %s", step.index + 1, e.what());
        }
      }
      t.predicted.push_back(st);
    }
    // Executed motion tokens: every segment sent, with the positions it passed through,
    // but one its entity was sent again in the same step (re-planned or re-decided).
    for (const auto& [id, seg] : segments_) {
      if (seg.sent == ros::Time()) continue;
      const bool replaced = std::any_of(segments_.begin(), segments_.end(), [&](const auto& other) {
        return other.second.entity == seg.entity && other.second.step == seg.step && other.second.sent > seg.sent;
      });
      if (replaced) continue;
      exec::ExecutedToken ex;
      try {
        ex.token = task::parseTokenKey(seg.key, spec_);
      } catch (const Error&) {
        continue;
      }
      ex.step = seg.step;
      ex.goal = seg.goal;
      ex.planned = seg.planned;
      ex.executed = seg.executed;
      auto pos = positions_.find(seg.entity);
      if (ex.executed.empty() && pos != positions_.end()) ex.executed.push_back(pos->second);
      if (ex.executed.empty()) continue;
      ex.start = ex.executed.front();
      t.executed.push_back(ex);
    }
    for (const auto& e : spec_.entities) {
      auto pos = positions_.find(e.name);
      t.final_positions.push_back(pos != positions_.end() ? pos->second : Eigen::Vector2d::Constant(NAN));
    }
    if (positions_.size() < spec_.entities.size()) t.final_positions.clear();
    return t;
  }

  /// `ending`: the run's ending as result.json names it: the coordinator's final state
  /// (finished, aborted, estopped), or the monitor's (interrupted, timed_out).
  void report(const std::string& outcome, const ddace::CoordinatorState& s, const std::string& ending = "") {
    if (reported_) return;
    reported_ = true;
    const bool finished = s.state == ddace::CoordinatorState::FINISHED;
    std::vector<std::vector<std::string>> executed, truth;
    for (const auto& step : s.steps) {
      executed.emplace_back();
      for (const auto& t : step.tokens) executed.back().push_back(keyOf(t));
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
    if (have_gt_) os << ", ground truth " << fs::path(gt_file_).filename().string();
    os << "\n";
    const size_t rows = std::max(executed.size(), truth.size());
    for (size_t k = 0; k < rows; ++k) {
      os << "  step " << k + 1 << ": " << (k < executed.size() ? stepText(executed[k]) : "(none)");
      if (have_gt_) {
        const bool same = k < executed.size() && k < truth.size() && executed[k] == truth[k];
        os << (same ? "   [= ground truth]"
                    : "   [ground truth: " + (k < truth.size() ? stepText(truth[k]) : "END") + "]");
      }
      os << "\n";
    }
    os << "  " << (finished ? "END" : "(no END)") << "\n";
    const double duration = s.steps.empty() ? 0.0 : (ros::Time::now() - s.steps.front().decided).toSec();
    os << "result: " << outcome << ", " << duration << " s from the first decision to the end, "
       << s.decisions_requested << " decisions requested\n";
    int gc_met = 0;
    for (size_t i = 0; i < s.goal_conditions.size() && i < s.goal_conditions_met.size(); ++i) {
      gc_met += s.goal_conditions_met[i] ? 1 : 0;
      os << "  goal condition " << s.goal_conditions[i] << ": " << (s.goal_conditions_met[i] ? "met" : "NOT met")
         << "\n";
    }
    const exec::Trial run = trial(s);
    nlohmann::json j;
    j["task"] = spec_.name;
    j["state"] = !ending.empty() ? ending : s.state_name;
    j["coordinator_state"] = have_state_ ? s.state_name : "none";
    j["outcome"] = outcome;
    j["reason"] = s.reason;
    j["steps"] = executed.size();
    j["goal_conditions"] = s.goal_conditions.size();
    j["goal_conditions_met"] = gc_met;
    j["duration_s"] = duration;
    if (have_gt_) {
      // One definition of every metric: the same scoring as `ddace eval`.
      const eval::TrialScore score = eval::scoreTrial(spec_, gt_, run);
      const bool collided = collisions_fail_ && !clearance_->collisions().empty();
      auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
      os << "metrics: SSR " << score.ssr() << " (" << score.correct_steps << "/" << score.gt_steps << " steps), GCR "
         << score.gcr() << " (" << score.achieved_robot_motions << "/" << score.gt_robot_motions
         << " robot motion tokens arrived), goal conditions " << (score.goal_conditions_hold ? "hold" : "do NOT hold")
         << ", FD " << score.meanFd() << ", OSR " << (score.success && !collided ? 1 : 0)
         << (score.success && collided ? " (a collision: no success)" : "") << "\n";
      j["ground_truth"] = fs::path(gt_file_).filename().string();
      j["ssr"] = score.ssr();
      j["gcr"] = score.gcr();
      j["fd"] = num(score.meanFd());
      j["osr"] = score.success && !collided ? 1 : 0;  // a collision is no success (collisions_fail)
      j["ended_correctly"] = score.ended_correctly;
      j["goal_conditions_hold"] = score.goal_conditions_hold;
    }
    const exec::ClosestApproach& near = clearance_->closest();
    const auto& hits = clearance_->collisions();
    os << "bodies: " << hits.size() << " collision" << (hits.size() == 1 ? "" : "s");
    for (const auto& c : hits) os << (&c == &hits.front() ? " (" : ", ") << nameOf(c.a) << "-" << nameOf(c.b);
    os << (hits.empty() ? "" : ")");
    if (near.a >= 0)
      os << ", minimum clearance " << near.clearance_m * 100 << " cm (" << nameOf(near.a) << "-" << nameOf(near.b)
         << ")";
    os << "\n";
    j["collisions"] = hits.size();
    j["min_clearance_m"] = near.a >= 0 ? nlohmann::json(near.clearance_m) : nlohmann::json(nullptr);
    j["closest_pair"] = near.a >= 0 ? nlohmann::json({nameOf(near.a), nameOf(near.b)}) : nlohmann::json(nullptr);
    const int violations = this->violations();
    os << "decisions requested while a segment was running: " << violations << "\n";
    j["decisions_while_running"] = violations;
    writeRunJson(s, run);
    stopBag();
    const bool bag = fs::exists(run_dir_ + "/run.bag");
    if (record_bag_) os << "bag: " << (bag ? "run.bag" : "NONE (rosbag record wrote no run.bag)") << "\n";
    j["bag"] = bag ? nlohmann::json("run.bag") : nlohmann::json(nullptr);
    const std::string plotted = plot();
    os << "plot: " << plotted << "\n";
    j["plot"] = plotted;
    os << "run directory: " << run_dir_ << "\n";
    std::cout << os.str() << std::flush;
    writeRecord("report.txt", os.str());
    writeRecord("result.json", j.dump(2) + "\n");
    if (end_launch_ && isRoslaunch(::getppid())) ::kill(::getppid(), SIGINT);  // a clean end of the whole launch
    ros::shutdown();
  }

  /// What the plot needs: per segment the planned path with its stddev, the executed
  /// positions, and when each step was decided.
  void writeRunJson(const ddace::CoordinatorState& s, const exec::Trial&) const {
    nlohmann::json j;
    j["task"] = spec_.name;
    j["state"] = s.state_name;
    j["reason"] = s.reason;
    const double t0 = s.steps.empty() ? 0.0 : s.steps.front().decided.toSec();
    j["decisions_s"] = nlohmann::json::array();
    for (const auto& step : s.steps) j["decisions_s"].push_back(step.decided.toSec() - t0);
    j["segments"] = nlohmann::json::array();
    for (const auto& [id, seg] : segments_) {
      if (seg.sent == ros::Time()) continue;
      nlohmann::json g;
      g["id"] = id;
      g["key"] = seg.key;
      g["entity"] = seg.entity;
      g["kind"] = spec_.entityIndex(seg.entity) >= 0
                      ? task::toString(spec_.entities[spec_.entityIndex(seg.entity)].kind)
                      : "unknown";
      g["step"] = seg.step;
      g["sent_s"] = seg.sent.toSec() - t0;
      g["ended_s"] = seg.ended == ros::Time() ? nlohmann::json(nullptr) : nlohmann::json(seg.ended.toSec() - t0);
      g["end_status"] = seg.end_status;
      g["goal"] = {seg.goal.x(), seg.goal.y()};
      for (const auto& p : seg.planned) g["planned"].push_back({p.x(), p.y()});
      g["stddev_m"] = seg.stddev_m;
      for (const auto& p : seg.executed) g["executed"].push_back({p.x(), p.y()});
      j["segments"].push_back(g);
    }
    // Bodies: the whole table in one view (footprints at the start and the end, the closest approach).
    j["bodies"] = nlohmann::json::array();
    for (size_t i = 0; i < spec_.entities.size(); ++i) {
      const auto& e = spec_.entities[i];
      const exec::BodyShape b = exec::bodyShape(spec_, static_cast<int>(i));
      nlohmann::json o;
      o["name"] = e.name;
      o["kind"] = task::toString(e.kind);
      o["radius_m"] = b.radius_m;
      o["obstacle"] = b.obstacle;
      if (auto it = starts_.find(e.name); it != starts_.end()) o["start"] = {it->second.x(), it->second.y()};
      if (auto it = positions_.find(e.name); it != positions_.end()) o["end"] = {it->second.x(), it->second.y()};
      j["bodies"].push_back(o);
    }
    const exec::ClosestApproach& near = clearance_->closest();
    if (near.a >= 0)
      j["closest"] = {{"a", nameOf(near.a)},
                      {"b", nameOf(near.b)},
                      {"clearance_m", near.clearance_m},
                      {"time_s", near.time_s - t0},
                      {"at_a", {near.at_a.x(), near.at_a.y()}},
                      {"at_b", {near.at_b.x(), near.at_b.y()}}};
    j["collisions"] = nlohmann::json::array();
    for (const auto& c : clearance_->collisions())
      j["collisions"].push_back({{"a", nameOf(c.a)}, {"b", nameOf(c.b)}, {"time_s", c.time_s - t0}});
    writeRecord("run.json", j.dump() + "\n");
  }

  /// Writes one file of the run directory, checked and atomic; a failure (a full disk)
  /// is logged naming the file, and the run's other files are still written.
  void writeRecord(const std::string& name, const std::string& text) const {
    try {
      writeTextFile(run_dir_ + "/" + name, text);
    } catch (const std::exception& e) {
      ROS_ERROR_STREAM("execution monitor: the run record is incomplete: " << e.what());
    }
  }

  /// Runs plot_script on run.json; returns "paths.png" or why there is no plot.
  std::string plot() const {
    if (plot_script_.empty()) return "none (parameter plot_script is empty)";
    if (!fs::exists(plot_script_)) {
      const std::string why =
          "NONE: the plot script " + plot_script_ + " does not exist (build or install ddace, or set ~plot_script)";
      ROS_ERROR("execution_monitor: %s", why.c_str());
      return why;
    }
    const std::string cmd = "/usr/bin/python3 '" + plot_script_ + "' '" + run_dir_ + "/run.json' '" + run_dir_ +
                            "/paths.png' > '" + run_dir_ + "/plot.log' 2>&1";
    if (std::system(cmd.c_str()) != 0 || !fs::exists(run_dir_ + "/paths.png")) {
      ROS_ERROR("execution_monitor: the plot failed (see %s/plot.log)", run_dir_.c_str());
      return "NONE: " + plot_script_ + " failed (see plot.log)";
    }
    return "paths.png";
  }

  task::TaskSpec spec_;
  task::Demonstration gt_;
  std::string gt_file_, run_dir_, latest_link_, plot_script_;
  bool have_gt_ = false, reported_ = false, have_state_ = false, end_launch_ = true;
  ddace::CoordinatorState last_state_;
  std::map<uint32_t, Seg> segments_;
  std::map<std::string, uint32_t> running_;  ///< entity -> its latest segment
  std::map<std::string, Eigen::Vector2d> positions_;
  std::map<std::string, Eigen::Vector2d> starts_;  ///< first tracked position of each entity
  std::unique_ptr<exec::ClearanceMeter> clearance_;
  std::vector<double> radii_;                     ///< every entity's footprint (0: a goal)
  std::unique_ptr<exec::StepContacts> contacts_;  ///< who may touch whom in the running step
  bool collisions_fail_ = true;                   ///< Params::collisions_fail
  std::vector<Eigen::Vector2d> at_;               ///< latest positions in the task's order (NaN = not seen)
  std::vector<ros::Time> requests_;
  std::set<uint32_t> request_ids_;
  std::vector<ros::Subscriber> subs_;
  ros::Timer timer_, final_timer_;
  ros::NodeHandle nh_;
  pid_t bag_pid_ = -1;
  bool record_bag_ = true, bag_failed_ = false;
  int poses_since_linked_ = -1;  ///< /ddace/entities messages received since every link was seen up (-1: one is not)
  ros::WallTimer link_timer_;
  std::string bag_exit_;                                       ///< how rosbag record ended, when it did by itself
  std::map<std::string, std::vector<std::string>> listeners_;  ///< node (this one, the recorder) -> its topics
  ros::ServiceServer ready_srv_;
  std::unique_ptr<HeartbeatPublisher> heartbeat_;
};

ExecutionMonitorNode::ExecutionMonitorNode(ros::NodeHandle nh, ros::NodeHandle pnh)
    : impl_(std::make_unique<Impl>(nh, pnh)) {}

ExecutionMonitorNode::~ExecutionMonitorNode() = default;

}  // namespace ddace::nodes
