// Shared by the rostests of the execution graph (exec_*.cpp): generate a task, start
// launch/execute_sim.launch as a child roslaunch on rostest's master, and watch the wire.
//
// The graph is started from the test (not from the .test file) because its nodes need the
// task directory, which the test generates first.
#pragma once

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <ros/network.h>
#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <std_msgs/Bool.h>
#include <std_srvs/Trigger.h>
#include <yaml-cpp/yaml.h>

#include <ddace/CoordinatorState.h>
#include <ddace/Decision.h>
#include <ddace/DecisionRequest.h>
#include <ddace/EntityArray.h>
#include <ddace/PathRequest.h>
#include <ddace/PathResponse.h>
#include <ddace/Segment.h>
#include <ddace/SegmentStatus.h>
#include <ddace/WheelCommand.h>

#include "ddace/pipeline/evaluation.h"
#include "ddace/task/task_dir.h"
#include "ddace/tasks/generators.h"

namespace exec_test {

namespace fs = std::filesystem;

/// A fresh directory under ROS_HOME (or /tmp) for this test's files, removed at the end.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name) {
    const char* home = std::getenv("ROS_HOME");
    path_ = (fs::path(home ? home : "/tmp") / ("ddace_" + name + "_" + std::to_string(::getpid()))).string();
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  operator const std::string&() const { return path_; }

 private:
  std::string path_;
};

/// Writes DIR/train and DIR/test of a generated family, like `ddace generate`.
inline void generateTask(const std::string& dir, const std::string& family, int train, int test, int robots = 11) {
  ddace::tasks::GeneratorOptions o;
  o.family = family;
  o.robots = robots;
  o.demos = train;
  o.seed = 5;
  ddace::task::writeTaskDir(ddace::tasks::generate(o), dir + "/train");
  o.demos = test;
  o.seed = 77;
  ddace::task::writeTaskDir(ddace::tasks::generate(o), dir + "/test");
}

/// Trains DIR/train into DIR/model as `ddace train` does with its defaults (pipeline::trainModel:
/// the default `scene` network and the GP primitive library). Returns the model directory.
inline std::string trainModel(const std::string& dir) {
  const ddace::task::TaskDir train = ddace::task::loadTaskDir(dir + "/train");
  const std::string model_dir = dir + "/model";
  const auto t0 = std::chrono::steady_clock::now();
  const ddace::pipeline::Model model =
      ddace::pipeline::trainModel(train, ddace::tgn::TrainOptions{}, model_dir, nullptr);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "trained " << model_dir << " in " << s << " s (" << model.sequence.info().history.size()
            << " epochs, step accuracy " << model.sequence.info().history.back().step_accuracy << ")\n";
  return model_dir;
}

/// `config` with some values replaced: {"coordinator", "segment_timeout_s", "3.0"}.
inline std::string writeConfig(const std::string& shipped, const std::string& out,
                               const std::vector<std::array<std::string, 3>>& overrides) {
  YAML::Node root = YAML::LoadFile(shipped);
  for (const auto& o : overrides) root[o[0]][o[1]] = YAML::Load(o[2]);
  std::ofstream f(out);
  f << root;
  return out;
}

/// roslaunch as a child process group; killed (SIGINT, then SIGKILL) on destruction.
/// With `log` its output goes to that file instead of the test's, and is printed when
/// the test has failed (the nodes' own account of what went wrong).
class Launch {
 public:
  explicit Launch(const std::vector<std::string>& args, const std::string& log = "") : log_(log) {
    pid_ = ::fork();
    if (pid_ == 0) {
      ::setpgid(0, 0);
      if (!log.empty()) {
        if (std::FILE* f = std::fopen(log.c_str(), "w")) {
          ::dup2(::fileno(f), 1);
          ::dup2(::fileno(f), 2);
        }
      }
      std::vector<char*> argv;
      argv.push_back(const_cast<char*>("roslaunch"));
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execvp("roslaunch", argv.data());
      ::_exit(127);
    }
    ::setpgid(pid_, pid_);
  }
  /// SIGINT to the launch's process group (Ctrl-C in its terminal).
  void interrupt() {
    if (pid_ > 0) ::kill(-pid_, SIGINT);
  }
  /// Waits until roslaunch exits by itself; true when it did within `timeout_s`.
  bool waitExit(double timeout_s) {
    for (int i = 0; i < timeout_s * 10 && pid_ > 0; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return pid_ <= 0;
  }
  ~Launch() {
    stop();
    if (!log_.empty() && ::testing::Test::HasFailure()) {
      std::ifstream f(log_);
      std::cout << "---- output of the launch (" << log_ << ") ----\n"
                << f.rdbuf() << "\n---- end of the launch's output\n";
    }
  }

 private:
  void stop() {
    if (pid_ <= 0) return;
    ::kill(-pid_, SIGINT);
    for (int i = 0; i < 150; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ::kill(-pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }

  pid_t pid_ = -1;
  std::string log_;
};

/// The process id of a running node, from its own XML-RPC getPid (-1 when unknown).
inline int pidOfNode(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return -1;
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(std::string(payload), host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), port, "/");
  XmlRpc::XmlRpcValue a, r;
  a[0] = ros::this_node::getName();
  if (!client.execute("getPid", a, r) || r.getType() != XmlRpc::XmlRpcValue::TypeArray || r.size() < 3) return -1;
  return static_cast<int>(r[2]);
}

/// Polls `pred` while callbacks run (an AsyncSpinner must be running).
inline bool waitFor(const std::function<bool()>& pred, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return pred();
}

/// waitFor with `pred` read under `mu`, the lock the test's callbacks write under.
inline bool waitFor(std::mutex& mu, const std::function<bool()>& pred, double timeout_s) {
  return waitFor(
      [&] {
        std::lock_guard<std::mutex> l(mu);
        return pred();
      },
      timeout_s);
}

/// A follow segment of `entity` along the straight line (x0, y0) -> (x1, y1) (table frame,
/// metres, 21 points), with token `entity`:`action`:G1 of step `step`, as the coordinator
/// sends one.
inline ddace::Segment straightSegment(const std::string& entity, const std::string& action, uint32_t id, int step,
                                      double x0, double y0, double x1, double y1, double arrival_radius_m) {
  ddace::Segment s;
  s.header.stamp = ros::Time::now();
  s.header.frame_id = "table";
  s.mode = ddace::Segment::MODE_FOLLOW;
  s.entity = entity;
  s.segment_id = id;
  s.step = step;
  s.token.entity = entity;
  s.token.action = action;
  s.token.target = "G1";
  s.token.probability = 1;
  for (int i = 0; i <= 20; ++i) {
    geometry_msgs::PoseStamped p;
    p.header = s.header;
    p.pose.position.x = x0 + (x1 - x0) * i / 20.0;
    p.pose.position.y = y0 + (y1 - y0) * i / 20.0;
    p.pose.orientation.w = 1;
    s.path.poses.push_back(p);
  }
  s.path.header = s.header;
  s.goal.x = x1;
  s.goal.y = y1;
  s.arrival_radius_m = arrival_radius_m;
  s.timeout_s = 30;
  return s;
}

/// An executor's final report on segment `segment_id` of `entity` (progress 1), stamped now.
inline ddace::SegmentStatus segmentStatus(const std::string& entity, uint32_t segment_id, uint8_t code) {
  ddace::SegmentStatus s;
  s.header.stamp = ros::Time::now();
  s.entity = entity;
  s.segment_id = segment_id;
  s.status = code;
  s.progress = 1;
  return s;
}

/// A sequence node's answer to `request` in a run of one step of one token, then END.
inline ddace::Decision oneTokenThenEnd(const ddace::DecisionRequest& request, const std::string& entity,
                                       const std::string& action, const std::string& target, double probability) {
  ddace::Decision d;
  d.id = request.id;
  if (request.step != 0) {
    d.end = true;
    return d;
  }
  ddace::Token t;
  t.entity = entity;
  t.action = action;
  t.target = target;
  t.probability = probability;
  d.tokens.push_back(t);
  return d;
}

/// A path node's answer to `m`: the straight line from its start to its goal.
inline ddace::PathResponse straightPath(const ddace::PathRequest& m) {
  ddace::PathResponse r;
  r.id = m.id;
  r.path.header.frame_id = "table";
  for (const auto& p : {m.start, m.goal}) {
    geometry_msgs::PoseStamped ps;
    ps.pose.position = p;
    ps.pose.orientation.w = 1;
    r.path.poses.push_back(ps);
  }
  return r;
}

/// One entity as a tracker reports it (table frame, metres).
struct TrackedEntity {
  std::string name, kind;
  double x, y;
};

/// The tracker's stand-in: publishes /ddace/entities at 30 Hz, each frame from `now()` (so
/// a test moves an entity by changing what `now` returns), until destroyed.
class FakeTracker {
 public:
  explicit FakeTracker(std::function<std::vector<TrackedEntity>()> now)
      : pub_(ros::NodeHandle().advertise<ddace::EntityArray>("/ddace/entities", 5)),
        now_(std::move(now)),
        thread_([this] {
          ros::Rate rate(30);
          while (run_) {
            ddace::EntityArray arr;
            arr.header.stamp = ros::Time::now();
            arr.header.frame_id = "table";
            for (const auto& e : now_()) {
              ddace::Entity en;
              en.name = e.name;
              en.kind = e.kind;
              en.pose.x = e.x;
              en.pose.y = e.y;
              en.visible = true;
              arr.entities.push_back(en);
            }
            pub_.publish(arr);
            rate.sleep();
          }
        }) {}
  ~FakeTracker() {
    run_ = false;
    thread_.join();
  }

 private:
  ros::Publisher pub_;
  std::function<std::vector<TrackedEntity>()> now_;
  std::atomic<bool> run_{true};
  std::thread thread_;
};

/// A wheel command as received: its stamp, its speeds and the node that published it.
struct Wheel {
  ros::Time stamp;
  double left, right;
  std::string from;
  bool zero() const { return left == 0 && right == 0; }
};

/// The stop rule in control cycles, not wall time: of `cmds` (one publisher's, in the order
/// it published them) those stamped after `event` are at most `cycles` non-zero commands
/// (1: the cycle under way when the event reached it) and then only zeros, at least one.
inline ::testing::AssertionResult zeroWithinCycles(const std::vector<Wheel>& cmds, const ros::Time& event, int cycles) {
  int after = 0, zeros = 0;
  for (const auto& c : cmds) {
    if (c.stamp <= event) continue;
    ++after;
    if (c.zero()) {
      ++zeros;
    } else if (after > cycles || zeros > 0) {
      return ::testing::AssertionFailure() << "command " << after << " after the event (" << (c.stamp - event).toSec()
                                           << " s) is non-zero: " << c.left << ", " << c.right;
    }
  }
  if (zeros == 0) return ::testing::AssertionFailure() << "no zero command after the event (" << after << " commands)";
  return ::testing::AssertionSuccess();
}

inline ::testing::AssertionResult zeroWithinOneCycle(const std::vector<Wheel>& cmds, const ros::Time& event) {
  return zeroWithinCycles(cmds, event, 1);
}

/// The commands of `cmds` published by `node`.
inline std::vector<Wheel> from(const std::vector<Wheel>& cmds, const std::string& node) {
  std::vector<Wheel> out;
  for (const auto& c : cmds)
    if (c.from == node) out.push_back(c);
  return out;
}

/// The first zero command of `cmds` stamped at or after `t` (ros::Time() when none).
inline ros::Time firstZeroAfter(const std::vector<Wheel>& cmds, const ros::Time& t) {
  for (const auto& c : cmds)
    if (c.stamp >= t && c.zero()) return c.stamp;
  return ros::Time();
}

/// Everything on the wire that the tests judge.
class Watcher {
 public:
  struct Seg {
    std::string key;
    int step = -1;
    ros::Time sent, ended;
    uint8_t end_status = 0;
  };

  Watcher(ros::NodeHandle& nh, const ddace::task::TaskSpec& spec) {
    for (const auto& e : spec.entities) {
      if (e.kind == ddace::task::EntityKind::Goal) continue;
      const std::string n = e.name;
      subs_.push_back(
          nh.subscribe<ddace::Segment>("/robots/" + n + "/segment", 50, [this](const ddace::Segment::ConstPtr& m) {
            std::lock_guard<std::mutex> l(mu_);
            if (m->mode != ddace::Segment::MODE_FOLLOW) return;
            segments_[m->segment_id].key = m->token.entity + ":" + m->token.action + ":" + m->token.target;
            segments_[m->segment_id].sent = m->header.stamp;
            segments_[m->segment_id].step = m->step;
          }));
      subs_.push_back(nh.subscribe<ddace::SegmentStatus>("/robots/" + n + "/segment_status", 100,
                                                         [this](const ddace::SegmentStatus::ConstPtr& m) {
                                                           std::lock_guard<std::mutex> l(mu_);
                                                           if (m->status < ddace::SegmentStatus::DONE) return;
                                                           Seg& s = segments_[m->segment_id];
                                                           if (s.ended == ros::Time())
                                                             s.ended = m->header.stamp, s.end_status = m->status;
                                                         }));
      if (e.kind == ddace::task::EntityKind::Robot)
        subs_.push_back(nh.subscribe<ddace::WheelCommand>(
            "/robots/" + n + "/wheels", 200,
            boost::function<void(const ros::MessageEvent<const ddace::WheelCommand>&)>(
                [this, n](const ros::MessageEvent<const ddace::WheelCommand>& ev) {
                  const auto& m = *ev.getConstMessage();
                  std::lock_guard<std::mutex> l(mu_);
                  wheels_[n].push_back({m.header.stamp, m.left_mps, m.right_mps, ev.getPublisherName()});
                })));
    }
    subs_.push_back(nh.subscribe<ddace::DecisionRequest>("/ddace/decision_request", 20,
                                                         [this](const ddace::DecisionRequest::ConstPtr& m) {
                                                           std::lock_guard<std::mutex> l(mu_);
                                                           // A re-sent request (same id) counts once.
                                                           if (request_ids_.insert(m->id).second)
                                                             requests_.push_back(m->header.stamp);
                                                         }));
    subs_.push_back(nh.subscribe<ddace::CoordinatorState>("/coordinator/state", 20,
                                                          [this](const ddace::CoordinatorState::ConstPtr& m) {
                                                            std::lock_guard<std::mutex> l(mu_);
                                                            state_ = *m;
                                                            have_state_ = true;
                                                            first_stamp_.emplace(m->state, m->header.stamp);
                                                          }));
  }

  /// Waits until every subscription is connected to a publisher, and to every publisher the
  /// master lists for its topic: the graph starts after this watcher, and a run started
  /// before the links stand loses its first messages (seen under load: the first decision
  /// request went uncounted; a robot's wheels linked to its follower but not yet to the
  /// coordinator missed the coordinator's zeros). Returns the topics still short of a
  /// publisher (empty when all are connected).
  std::vector<std::string> waitConnected(double timeout_s) {
    std::vector<std::string> missing;
    waitFor(
        [&] {
          missing.clear();
          const auto listed = masterPublisherCounts();
          for (const auto& sub : subs_) {
            auto it = listed.find(sub.getTopic());
            const size_t want = std::max<size_t>(1, it == listed.end() ? 0 : it->second);
            if (sub.getNumPublishers() < want) missing.push_back(sub.getTopic());
          }
          return missing.empty();
        },
        timeout_s);
    return missing;
  }

  /// The number of publishers the master lists for each topic (empty if it cannot be asked).
  static std::map<std::string, size_t> masterPublisherCounts() {
    XmlRpc::XmlRpcValue request, response, payload;
    request[0] = ros::this_node::getName();
    std::map<std::string, size_t> out;
    if (!ros::master::execute("getSystemState", request, response, payload, false)) return out;
    XmlRpc::XmlRpcValue& publishers = payload[0];
    for (int i = 0; i < publishers.size(); ++i)
      out[static_cast<std::string>(publishers[i][0])] = static_cast<size_t>(publishers[i][1].size());
    return out;
  }

  bool haveState() {
    std::lock_guard<std::mutex> l(mu_);
    return have_state_;
  }
  ddace::CoordinatorState state() {
    std::lock_guard<std::mutex> l(mu_);
    return state_;
  }
  uint8_t stateCode() { return state().state; }
  /// The stamp of the first ~state in `state` (ros::Time() before one came).
  ros::Time firstStamp(uint8_t state) {
    std::lock_guard<std::mutex> l(mu_);
    auto it = first_stamp_.find(state);
    return it == first_stamp_.end() ? ros::Time() : it->second;
  }
  /// Forgets the states seen so far (before a new run of the same graph).
  void clearStates() {
    std::lock_guard<std::mutex> l(mu_);
    first_stamp_.clear();
  }
  std::map<std::string, std::vector<Wheel>> wheels() {
    std::lock_guard<std::mutex> l(mu_);
    return wheels_;
  }
  std::map<uint32_t, Seg> segments() {
    std::lock_guard<std::mutex> l(mu_);
    return segments_;
  }

  /// Decision requests stamped while some segment was running (sent, not yet ended).
  std::vector<std::string> decisionsWhileRunning() {
    std::lock_guard<std::mutex> l(mu_);
    std::vector<std::string> bad;
    for (const auto& r : requests_)
      for (const auto& [id, s] : segments_)
        if (s.sent != ros::Time() && s.sent < r && (s.ended == ros::Time() || r < s.ended))
          bad.push_back("request at " + std::to_string(r.toSec()) + " while " + s.key + " ran");
    return bad;
  }
  size_t requests() {
    std::lock_guard<std::mutex> l(mu_);
    return requests_.size();
  }

 private:
  std::mutex mu_;
  std::vector<ros::Subscriber> subs_;
  std::map<std::string, std::vector<Wheel>> wheels_;
  std::map<uint32_t, Seg> segments_;
  std::vector<ros::Time> requests_;
  std::set<uint32_t> request_ids_;
  ddace::CoordinatorState state_;
  std::map<uint8_t, ros::Time> first_stamp_;
  bool have_state_ = false;
};

/// Calls a Trigger service until it exists and succeeds (the graph may still be connecting).
inline bool trigger(const std::string& service, double timeout_s, std::string* message = nullptr) {
  return waitFor(
      [&] {
        std_srvs::Trigger t;
        if (!ros::service::exists(service, false) || !ros::service::call(service, t)) return false;
        if (message) *message = t.response.message;
        return static_cast<bool>(t.response.success);
      },
      timeout_s);
}

/// Starts the run once the watcher's links stand (a run started earlier loses its first
/// messages). Returns "" or what went wrong.
inline std::string startRun(Watcher& watch, double timeout_s) {
  const auto unconnected = watch.waitConnected(timeout_s);
  if (!unconnected.empty()) return "no publisher on " + unconnected.front();
  std::string msg;
  if (!trigger("/coordinator/start", timeout_s, &msg)) return "could not start the run: " + msg;
  return "";
}

/// How a run started by runToEnd ended.
struct RunEnd {
  std::string not_started;        ///< what kept the run from starting ("" when it started)
  bool ended = false;             ///< finished, aborted or e-stopped within timeout_s
  double timeout_s = 0;           ///< the time it was given to end
  ddace::CoordinatorState state;  ///< the coordinator's last state
};

/// Waits up to `timeout_s` for a started run to end: finished, aborted or e-stopped; then a
/// moment for the last statuses and wheel commands.
inline RunEnd waitRunEnd(Watcher& watch, double timeout_s) {
  RunEnd run;
  run.timeout_s = timeout_s;
  run.ended = waitFor(
      [&] {
        const auto c = watch.stateCode();
        return c == ddace::CoordinatorState::FINISHED || c == ddace::CoordinatorState::ABORTED ||
               c == ddace::CoordinatorState::ESTOPPED;
      },
      timeout_s);
  ros::Duration(0.3).sleep();
  run.state = watch.state();
  return run;
}

/// Starts the run once the watcher's links stand (startRun, up to `start_timeout_s`) and
/// waits up to `end_timeout_s` for it to end (waitRunEnd).
inline RunEnd runToEnd(Watcher& watch, double start_timeout_s, double end_timeout_s) {
  const std::string not_started = startRun(watch, start_timeout_s);
  if (not_started.empty()) return waitRunEnd(watch, end_timeout_s);
  RunEnd run;
  run.timeout_s = end_timeout_s;
  run.not_started = not_started;
  return run;
}

/// Success when `run` started, ended and finished; else which of these failed and why.
inline ::testing::AssertionResult finished(const RunEnd& run) {
  if (!run.not_started.empty()) return ::testing::AssertionFailure() << run.not_started;
  if (!run.ended)
    return ::testing::AssertionFailure() << "run did not end within " << run.timeout_s << " s; state "
                                         << run.state.state_name;
  if (run.state.state != ddace::CoordinatorState::FINISHED)
    return ::testing::AssertionFailure() << run.state.state_name << ": " << run.state.reason;
  return ::testing::AssertionSuccess();
}

/// Success when the coordinator judged every goal condition of `s` met; else those not met.
inline ::testing::AssertionResult goalConditionsMet(const ddace::CoordinatorState& s) {
  std::string unmet;
  for (size_t i = 0; i < s.goal_conditions_met.size(); ++i)
    if (!s.goal_conditions_met[i]) unmet += "\n  not met: " + s.goal_conditions.at(i);
  if (!unmet.empty()) return ::testing::AssertionFailure() << unmet;
  return ::testing::AssertionSuccess();
}

/// Success when every robot the watcher saw got wheel commands and its last one is a stop.
inline ::testing::AssertionResult wheelsStopped(Watcher& watch) {
  std::string wrong;
  for (const auto& [robot, cmds] : watch.wheels()) {
    if (cmds.empty()) wrong += "\n  " + robot + ": no wheel command";
    else if (cmds.back().left != 0.0 || cmds.back().right != 0.0) wrong += "\n  " + robot + " still driving at the end";
  }
  if (!wrong.empty()) return ::testing::AssertionFailure() << wrong;
  return ::testing::AssertionSuccess();
}

/// The simulated table's true poses (/ddace/true_entities): each entity's first and last.
class TrueTable {
 public:
  explicit TrueTable(ros::NodeHandle& nh)
      : sub_(
            nh.subscribe<ddace::EntityArray>("/ddace/true_entities", 10, [this](const ddace::EntityArray::ConstPtr& m) {
              const std::lock_guard<std::mutex> l(mu_);
              for (const auto& e : m->entities) {
                first_.emplace(e.name, e);
                last_[e.name] = e;
              }
            })) {}
  std::map<std::string, ddace::Entity> first() const {
    const std::lock_guard<std::mutex> l(mu_);
    return first_;
  }
  std::map<std::string, ddace::Entity> last() const {
    const std::lock_guard<std::mutex> l(mu_);
    return last_;
  }

 private:
  mutable std::mutex mu_;
  std::map<std::string, ddace::Entity> first_, last_;
  ros::Subscriber sub_;  // last: its callback ends before the maps go
};

/// Step token keys of a demonstration, sorted per step.
inline std::vector<std::vector<std::string>> truthSteps(const ddace::task::Demonstration& d,
                                                        const ddace::task::TaskSpec& spec) {
  std::vector<std::vector<std::string>> out;
  for (const auto& s : d.steps) {
    out.emplace_back();
    for (const auto& t : s.tokens) out.back().push_back(ddace::task::tokenKey(t, spec));
    std::sort(out.back().begin(), out.back().end());
  }
  return out;
}

inline std::vector<std::vector<std::string>> executedSteps(const ddace::CoordinatorState& s) {
  std::vector<std::vector<std::string>> out;
  for (const auto& step : s.steps) {
    out.emplace_back();
    for (const auto& t : step.tokens)
      out.back().push_back(t.entity + ":" + t.action + (t.target.empty() ? "" : ":" + t.target));
    std::sort(out.back().begin(), out.back().end());
  }
  return out;
}

/// Parameters every graph test gets from its .test file (~execute_sim: optional).
struct Files {
  std::string launch_file, config_file, execute_sim;
  static Files fromParams() {
    ros::NodeHandle pnh("~");
    Files f;
    if (!pnh.getParam("launch_file", f.launch_file) || !pnh.getParam("config_file", f.config_file))
      throw std::runtime_error("the .test file must set ~launch_file and ~config_file");
    pnh.getParam("execute_sim", f.execute_sim);
    return f;
  }
};

/// The whole of a text file ("" when it cannot be read).
inline std::string readFile(const std::string& path) {
  std::ifstream f(path);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

/// The set-up of a graph test: a generated task (generateTask: DIR/train and DIR/test) in
/// a scratch directory of its own, the .test file's files, and execute_sim.launch's
/// arguments for them.
struct TaskGraph {
  ros::NodeHandle nh;
  Files files = Files::fromParams();
  ScratchDir scratch;
  ddace::task::TaskDir test;  ///< DIR/test: the scene and the ground truth

  TaskGraph(const std::string& name, const std::string& family, int train, int test_demos, int robots = 11)
      : scratch(name) {
    generateTask(scratch, family, train, test_demos, robots);
    test = ddace::task::loadTaskDir(dir() + "/test");
  }
  const std::string& dir() const { return scratch; }
  /// The shipped config with `overrides` (writeConfig), in the scratch directory.
  std::string config(const std::vector<std::array<std::string, 3>>& overrides) const {
    return writeConfig(files.config_file, dir() + "/execution.yaml", overrides);
  }
  /// execute_sim.launch on the task, the run started by the test (autostart:=false), then `extra`.
  std::vector<std::string> args(const std::vector<std::string>& extra) const {
    std::vector<std::string> a{files.launch_file, "task:=" + dir() + "/test", "train:=" + dir() + "/train",
                               "autostart:=false"};
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
};

/// The exit status of `scripts/execute_sim --check RUN_DIR` (-1 when it did not run).
inline int checkRun(const Files& files, const std::string& run_dir) {
  if (files.execute_sim.empty()) return -1;
  const int status = std::system(("'" + files.execute_sim + "' --check '" + run_dir + "' > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Demonstrations a learned run trains on. Task 2's test scene here has R10 nearer to R3 than
/// R2 is, which one of the first 10 training demonstrations shows: from those the scene
/// network is undecided whether R10 joins the first step (p = 0.5, tipped by the mock
/// robots' pose noise); from 20 it is not (p < 0.01).
inline constexpr int kLearnedDemos = 20;

/// Runs a generated task end-to-end on mock robots (scene and ground truth: test demo 0),
/// with a model trained here on kLearnedDemos demonstrations (`learned`) or replaying the
/// demonstration and checks what a user depends on: the ground-truth step sequence, END,
/// every goal condition, no decision while a segment runs, all wheels zero at the end.
inline void runTaskEndToEnd(const std::string& family, int robots, bool learned, double timeout_s) {
  ros::NodeHandle nh;
  const Files files = Files::fromParams();
  const ScratchDir scratch(family);
  const std::string& dir = scratch;
  generateTask(dir, family, learned ? kLearnedDemos : 3, 1, robots);
  std::vector<std::string> extra_args;
  if (learned) extra_args.push_back("model:=" + trainModel(dir));
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(dir + "/test");
  Watcher watch(nh, test.spec);
  std::vector<std::string> args = {files.launch_file,  "task:=" + dir + "/test", "train:=" + dir + "/train",
                                   "autostart:=false", "monitor:=false",         "config:=" + files.config_file};
  args.insert(args.end(), extra_args.begin(), extra_args.end());
  Launch graph(args);
  const RunEnd run = runToEnd(watch, 30.0, timeout_s);
  ASSERT_TRUE(finished(run));
  const ddace::CoordinatorState& s = run.state;
  EXPECT_EQ(executedSteps(s), truthSteps(test.demos.front(), test.spec));
  ASSERT_EQ(s.goal_conditions_met.size(), test.spec.goal_conditions.size());
  EXPECT_TRUE(goalConditionsMet(s));
  for (const auto& step : s.steps)
    for (size_t i = 0; i < step.tokens.size(); ++i)
      EXPECT_EQ(step.status[i], ddace::SegmentStatus::DONE) << step.tokens[i].entity << " in step " << step.index;
  EXPECT_EQ(watch.requests(), test.demos.front().steps.size() + 1) << "one decision per step plus END";
  const auto bad = watch.decisionsWhileRunning();
  EXPECT_TRUE(bad.empty()) << bad.front();
  for (const auto& [robot, cmds] : watch.wheels()) {
    ASSERT_FALSE(cmds.empty()) << robot;
    EXPECT_EQ(cmds.back().left, 0.0) << robot << " still driving at the end";
    EXPECT_EQ(cmds.back().right, 0.0) << robot;
  }
}

/// The main() of a rostest that watches the wire: its callbacks run on two spinner threads
/// while the test waits on conditions.
inline int rostestMain(int argc, char** argv, const std::string& node) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}

}  // namespace exec_test
