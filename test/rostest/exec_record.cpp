// What an operator watches and keeps: ~state at its rate during a step with live progress
// and distance; reset returns the run to its initial state and a start after it runs the
// task from the current poses; the run's directory holds a readable bag and the plot.
#include <algorithm>
#include <set>
#include <sstream>

#include "exec_common.h"

using namespace exec_test;

namespace {

/// Column `field` of every message on `topic` in `bag` (`rostopic echo -b -p`: one CSV row
/// per message, e.g. field.segment_id, field.header.stamp in nanoseconds).
std::vector<std::string> bagColumn(const std::string& bag, const std::string& topic, const std::string& field) {
  const std::string out = bag + "." + std::to_string(std::hash<std::string>()(topic)) + ".csv";
  if (std::system(("rostopic echo -b '" + bag + "' -p " + topic + " > '" + out + "' 2>&1").c_str()) != 0) return {};
  std::ifstream f(out);
  std::string line;
  std::vector<std::string> values;
  int column = -1;
  while (std::getline(f, line)) {
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    if (column < 0) {
      const auto it = std::find(cells.begin(), cells.end(), field);
      if (it == cells.end()) return {};
      column = static_cast<int>(it - cells.begin());
    } else if (column < static_cast<int>(cells.size())) {
      values.push_back(cells[column]);
    }
  }
  return values;
}

bool contains(const std::vector<std::string>& values, const std::string& v) {
  return std::find(values.begin(), values.end(), v) != values.end();
}

}  // namespace

TEST(ExecRecord, StateIsLiveResetRestartsAndTheRunLeavesARecord) {
  ros::NodeHandle nh;
  const Files files = Files::fromParams();
  const ScratchDir scratch("record");
  generateTask(scratch, "task4", 3, 1, 4);
  const ddace::task::TaskDir test = ddace::task::loadTaskDir(std::string(scratch) + "/test");
  const std::string run_dir = std::string(scratch) + "/run";
  std::mutex mu;
  std::vector<ddace::CoordinatorState> states;
  ros::Subscriber sub =
      nh.subscribe<ddace::CoordinatorState>("/coordinator/state", 100, [&](const ddace::CoordinatorState::ConstPtr& m) {
        std::lock_guard<std::mutex> l(mu);
        states.push_back(*m);
      });
  Watcher w(nh, test.spec);
  Launch graph(
      {files.launch_file, "task:=" + std::string(scratch) + "/test", "train:=" + std::string(scratch) + "/train",
       "autostart:=true", "monitor:=true", "run_dir:=" + run_dir, "config:=" + files.config_file},
      std::string(scratch) + "/launch.log");
  // Autostart: the coordinator starts the run the moment it may, as early as it can be.
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::EXECUTING; }, 40.0))
      << "state " << w.state().state_name << ": " << w.state().reason;

  // During a step: ~state at ~5 Hz, the same state, progress and distance moving.
  {
    std::lock_guard<std::mutex> l(mu);
    states.clear();
  }
  ros::WallDuration(2.0).sleep();
  std::vector<ddace::CoordinatorState> window;
  {
    std::lock_guard<std::mutex> l(mu);
    window = states;
  }
  ASSERT_GE(window.size(), 8u) << "~state is not published at its rate (5 Hz) during a step";
  const auto& first = window.front();
  const auto& last = window.back();
  ASSERT_EQ(first.state, ddace::CoordinatorState::EXECUTING);
  ASSERT_EQ(last.state, ddace::CoordinatorState::EXECUTING);
  ASSERT_FALSE(first.segments.empty());
  ASSERT_EQ(first.segments.size(), last.segments.size());
  EXPECT_GT(last.segments[0].progress, first.segments[0].progress) << "progress stays at its first value";
  EXPECT_LT(last.segments[0].distance_to_goal_m, first.segments[0].distance_to_goal_m);
  EXPECT_GT(last.segments[0].elapsed_s, first.segments[0].elapsed_s);
  EXPECT_FALSE(last.last_decision.empty());
  EXPECT_EQ(last.completed_steps, 0u);

  // Reset mid-run: back to the initial state, robots stopped.
  ASSERT_TRUE(trigger("/coordinator/reset", 5.0));
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::IDLE; }, 2.0));
  ros::Duration(0.3).sleep();
  const auto idle = w.state();
  EXPECT_TRUE(idle.steps.empty());
  EXPECT_EQ(idle.decisions_requested, 0u);
  EXPECT_TRUE(idle.last_decision.empty());
  for (const auto& [robot, cmds] : w.wheels()) EXPECT_TRUE(cmds.back().left == 0 && cmds.back().right == 0) << robot;

  // Start again: the task runs from where the robots are now, to the end.
  std::string msg;
  ASSERT_TRUE(trigger("/coordinator/start", 10.0, &msg)) << msg;
  ASSERT_TRUE(waitFor([&] { return w.stateCode() == ddace::CoordinatorState::FINISHED; }, 60.0))
      << w.state().state_name << ": " << w.state().reason;
  const auto done = w.state();
  EXPECT_EQ(executedSteps(done), truthSteps(test.demos.front(), test.spec));
  EXPECT_EQ(done.decisions_requested, test.demos.front().steps.size() + 1) << "counters carried over the reset";
  for (bool met : done.goal_conditions_met) EXPECT_TRUE(met);

  // The monitor writes the record and ends the launch by itself.
  ASSERT_TRUE(graph.waitExit(30.0)) << "the launch did not end after the run finished";
  // A clean ending: no error or dead process in the launch's output, and the documented
  // check says finished.
  const std::string log = readFile(std::string(scratch) + "/launch.log");
  for (const std::string bad : {"[ERROR]", "[FATAL]", "has died", "REQUIRED"})
    EXPECT_EQ(log.find(bad), std::string::npos) << "'" << bad << "' in the output of a finished run:\n" << log;
  EXPECT_EQ(checkRun(files, run_dir), 0) << "execute_sim --check " << run_dir;
  const std::string result = readFile(run_dir + "/result.json");
  {
    // The same record with a goal condition not met: finished, but no success to the check.
    const std::string unmet_dir = std::string(scratch) + "/unmet";
    fs::create_directories(unmet_dir);
    std::string unmet = result;
    const std::string met = "\"goal_conditions_met\": ";
    const size_t at = unmet.find(met);
    ASSERT_NE(at, std::string::npos) << result;
    unmet.replace(at + met.size(), unmet.find_first_of(",\n}", at + met.size()) - at - met.size(), "0");
    std::ofstream(unmet_dir + "/result.json") << unmet;
    EXPECT_EQ(checkRun(files, unmet_dir), 1) << "execute_sim --check must fail a run whose goal condition is not met";
  }
  EXPECT_NE(result.find("\"state\": \"finished\""), std::string::npos) << result;
  // The record is of the run after the reset: the reset run's cut segments are not its motions.
  EXPECT_NE(result.find("\"gcr\": 1.0"), std::string::npos) << result;
  EXPECT_NE(result.find("\"osr\": 1"), std::string::npos) << result;
  EXPECT_NE(readFile(run_dir + "/report.txt").find("finished"), std::string::npos);
  ASSERT_TRUE(fs::exists(run_dir + "/run.bag")) << "no bag in " << run_dir;
  const std::string info = run_dir + "/bag_info.txt";
  ASSERT_EQ(std::system(("rosbag info " + run_dir + "/run.bag > " + info + " 2>&1").c_str()), 0) << readFile(info);
  const std::string bag = readFile(info);
  for (const std::string topic : {"/ddace/entities", "/coordinator/state", "/robots/R1/segment",
                                  "/robots/R1/segment_status", "/robots/R1/wheels"})
    EXPECT_NE(bag.find(topic), std::string::npos) << topic << " not in the bag:\n" << bag;
  // The bag holds the run from the start command on (the coordinator starts a run only
  // once the monitor's ~ready says the recorder is linked to every publisher and a pose
  // stamped after that has come): the first decision request (sent by the start itself),
  // the entities from before it, every wheel command of R1 published from it on, and the
  // run's first segment.
  const std::string bag_file = run_dir + "/run.bag";
  // The coordinator's ids start at its wall clock (exec::firstIdAt) and count up: the run's
  // first request is the bag's first one for step 0, and no request has a smaller id.
  const auto request_ids = bagColumn(bag_file, "/ddace/decision_request", "field.id");
  const auto request_steps = bagColumn(bag_file, "/ddace/decision_request", "field.step");
  const auto request_stamps = bagColumn(bag_file, "/ddace/decision_request", "field.header.stamp");
  ASSERT_EQ(request_ids.size(), request_stamps.size());
  ASSERT_EQ(request_ids.size(), request_steps.size());
  const auto first_request = std::find(request_steps.begin(), request_steps.end(), "0");
  ASSERT_NE(first_request, request_steps.end()) << "the run's first decision request is not in the bag";
  const std::string first_request_id = request_ids[static_cast<size_t>(first_request - request_steps.begin())];
  for (const auto& id : request_ids)
    EXPECT_GE(std::stoull(id), std::stoull(first_request_id)) << "a request before the run's first is in the bag";
  const uint64_t start_ns = std::stoull(request_stamps[static_cast<size_t>(first_request - request_steps.begin())]);
  const auto stampsIn = [&](const std::string& topic) {
    std::set<uint64_t> out;
    for (const auto& t : bagColumn(bag_file, topic, "field.header.stamp")) out.insert(std::stoull(t));
    return out;
  };
  const auto entities = stampsIn("/ddace/entities");
  ASSERT_FALSE(entities.empty()) << "/ddace/entities is not in the bag";
  EXPECT_LE(*entities.begin(), start_ns) << "/ddace/entities: the bag begins " << (*entities.begin() - start_ns) * 1e-9
                                         << " s after the run's start";
  const auto wheels = stampsIn("/robots/R1/wheels");
  ASSERT_FALSE(wheels.empty()) << "/robots/R1/wheels is not in the bag";
  size_t seen = 0;
  const auto received = w.wheels();  // a copy: the watcher still receives
  ASSERT_TRUE(received.count("R1")) << "the test received no wheel command of R1";
  for (const auto& cmd : received.at("R1")) {
    const uint64_t t = cmd.stamp.toNSec();
    // Before the run, or near the bag's end: R1's wheels have two publishers (the follower
    // and the coordinator), and one's last command may still be on its way when it closes.
    if (t < start_ns || t + 500'000'000ull > *wheels.rbegin()) continue;
    ++seen;
    EXPECT_TRUE(wheels.count(t)) << "R1's wheel command stamped " << (t - start_ns) * 1e-9
                                 << " s after the run's start is not in the bag";
  }
  EXPECT_GT(seen, 0u) << "no wheel command of R1 during the run";
  // The run's first segment: the first sent from its start on (the reset run's segments have
  // smaller ids; one whose sending the watcher missed is known only by its status, keyless).
  const auto segments = w.segments();
  const auto first_sent = std::find_if(segments.begin(), segments.end(), [&](const auto& s) {
    return !s.second.key.empty() && s.second.sent.toNSec() >= start_ns;
  });
  ASSERT_NE(first_sent, segments.end()) << "the test saw no segment sent from the run's start on";
  const auto& [first_id, first_seg] = *first_sent;
  const std::string entity = first_seg.key.substr(0, first_seg.key.find(':'));
  EXPECT_TRUE(
      contains(bagColumn(bag_file, "/robots/" + entity + "/segment", "field.segment_id"), std::to_string(first_id)))
      << "the run's first segment (" << first_seg.key << ", id " << first_id << ") is not in the bag";
  const std::string png = readFile(run_dir + "/paths.png");
  ASSERT_GT(png.size(), 1000u) << readFile(run_dir + "/plot.log");
  EXPECT_EQ(png.substr(1, 3), "PNG");
  EXPECT_NE(result.find("\"plot\": \"paths.png\""), std::string::npos) << result;
  EXPECT_NE(result.find("\"bag\": \"run.bag\""), std::string::npos) << result;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "exec_record_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
