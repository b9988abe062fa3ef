// The recorder's files: valid ddace-task/1, labels as set, crash-safe partial files.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include "../common/run_tool.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/task/task_dir.h"
#include "ddace/vision/recorder.h"

using namespace ddace;
using namespace ddace::vision;
namespace fs = std::filesystem;

namespace {

// The repository's config/, found at run time (common/repository.h).
const std::string& configDir() {
  static const std::string dir = (ddace::findRepository("", {"config"}) / "config/").string();
  return dir;
}

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() /
           ("ddace_recorder_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(path);
  }
  ~TempDir() { fs::remove_all(path); }
  static inline int counter = 0;
};

RecorderConfig shippedConfig() {
  return loadRecorderConfig(configDir() + "recorder.yaml", loadMarkerConfig(configDir() + "markers.yaml"));
}

std::vector<Eigen::Vector2d> positions(double t) {
  return {{0.1 + 0.1 * t, 0.2}, {0.1, 0.8}, {0.45, 0.3}, {0.45, 0.7}, {0.88, 0.5}};
}

}  // namespace

TEST(Recorder, ShippedConfigBuildsTheTaskFromTheMarkers) {
  const RecorderConfig c = shippedConfig();
  ASSERT_EQ(c.spec.entities.size(), 5u);
  EXPECT_EQ(c.spec.entities[4].name, "G1");
  EXPECT_EQ(c.spec.entities[4].kind, task::EntityKind::Goal);
  EXPECT_EQ(c.spec.entities[0].type, "hamster");
  EXPECT_EQ(c.spec.actions, (std::vector<std::string>{"move", "stop"}));
  EXPECT_DOUBLE_EQ(c.rate_hz, 30.0);
  EXPECT_EQ(c.output_dir.find('~'), std::string::npos);
}

TEST(Recorder, ConfigErrorsNameTheLine) {
  const MarkerConfig m = loadMarkerConfig(configDir() + "markers.yaml");
  try {
    parseRecorderConfig("output_dir: /tmp/x\ntask:\n  name: t\n  goal_conditions:\n    - {entity: R9, at: G1}\n",
                        "r.yaml", m);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.diagnostics().front().str(),
              "r.yaml:5:7: goal condition names 'R9', which is not an entity of markers.yaml");
  }
  // A tolerance of 0 (task.yaml's reader refuses it; found by fuzzing).
  try {
    parseRecorderConfig(
        "output_dir: /tmp/x\ntask:\n  name: t\n  goal_conditions:\n    - {entity: R4, at: G1, tolerance: 0.00}\n",
        "r.yaml", m);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.diagnostics().front().str(), "r.yaml:5:39: tolerance must be positive (metres)");
  }
  EXPECT_THROW(parseRecorderConfig("task: {name: t}\n", "r.yaml", m), Error);  // no output_dir
  EXPECT_THROW(parseRecorderConfig("output_dir: /tmp/x\ntask: {name: t}\nrate: 3\n", "r.yaml", m), Error);
}

TEST(Recorder, WritesADemonstrationThatValidatesWithItsLabels) {
  TempDir dir;
  const RecorderConfig c = shippedConfig();
  DemoRecorder rec(c.spec, dir.path.string(), 1.0);
  const std::string path = rec.start(100.0);
  EXPECT_EQ(fs::path(path).filename(), "demo_000.csv");
  EXPECT_TRUE(fs::exists(rec.partialPath()));
  for (int i = 0; i < 90; ++i) {
    const double t = 100.0 + i / 30.0;
    if (i == 10) {
      rec.setLabel("R1", "move", "R3");
      rec.setLabel("R2", "move", "R3");
    }
    if (i == 40) {
      rec.setLabel("R1", "idle", "");
      rec.setLabel("R2", "", "");
    }
    if (i == 50) rec.setLabel("R3", "stop", "");
    if (i == 60) rec.setLabel("R3", "idle", "");
    EXPECT_TRUE(rec.addRow(t, positions(t - 100.0)));
  }
  EXPECT_FALSE(rec.addRow(100.5, positions(0.5)));  // time went backwards: dropped
  EXPECT_EQ(rec.stop(), path);
  EXPECT_FALSE(fs::exists(path + ".partial"));

  const task::TaskDirReport report = task::checkTaskDir(dir.path.string());
  ASSERT_TRUE(report.errors.empty()) << formatDiagnostics(report.errors);
  ASSERT_EQ(report.dir.demos.size(), 1u);
  const task::Demonstration& d = report.dir.demos[0];
  EXPECT_EQ(d.rows(), 90u);
  EXPECT_NEAR(d.t[30], 1.0, 1e-6);
  EXPECT_NEAR(d.positions[30][0].x(), 0.2, 1e-6);
  ASSERT_EQ(d.steps.size(), 2u);
  EXPECT_EQ(d.steps[0].keyframe_row, 10);
  EXPECT_EQ(task::tokenKey(d.steps[0].tokens[0], report.dir.spec), "R1:move:R3");
  EXPECT_EQ(d.steps[1].keyframe_row, 50);
  EXPECT_EQ(task::tokenKey(d.steps[1].tokens[0], report.dir.spec), "R3:stop");

  // A second demonstration in the same directory gets the next number.
  DemoRecorder again(c.spec, dir.path.string(), 1.0);
  EXPECT_EQ(fs::path(again.start(0.0)).filename(), "demo_001.csv");
  again.discard();
  EXPECT_FALSE(fs::exists(dir.path / "demos" / "demo_001.csv.partial"));
}

TEST(Recorder, RefusesBadLabelsWithoutChangingAnything) {
  TempDir dir;
  DemoRecorder rec(shippedConfig().spec, dir.path.string());
  rec.start(0.0);
  rec.setLabel("R1", "move", "G1");
  EXPECT_THROW(rec.setLabel("R7", "move", "G1"), Error);   // unknown entity
  EXPECT_THROW(rec.setLabel("R1", "dance", "G1"), Error);  // not in the vocabulary
  EXPECT_THROW(rec.setLabel("R1", "move", "R1"), Error);   // itself
  EXPECT_THROW(rec.setLabel("R1", "move", "X"), Error);    // unknown target
  EXPECT_THROW(rec.setLabel("R1", "", "G1"), Error);       // target without action
  EXPECT_THROW(rec.setLabel("G1", "move", "R1"), Error);   // goals take no labels
  EXPECT_EQ(rec.label(0).action, "move");
  EXPECT_EQ(rec.label(0).target, 4);
  EXPECT_THROW(rec.start(1.0), Error);  // already recording
  rec.discard();
}

TEST(Recorder, AKilledRecorderLeavesAReadablePartialFile) {
  TempDir dir;
  const RecorderConfig c = shippedConfig();
  std::string partial;
  {
    DemoRecorder rec(c.spec, dir.path.string(), 1.0);
    rec.start(0.0);
    rec.setLabel("R1", "move", "G1");
    for (int i = 0; i < 70; ++i) rec.addRow(i / 30.0, positions(i / 30.0));
    partial = rec.partialPath();
    // Rows up to the last flush (t >= 1 s) are on disk before anything is closed.
    const std::string text = readTextFile(partial);
    const size_t lines = static_cast<size_t>(std::count(text.begin(), text.end(), '\n'));
    EXPECT_GE(lines, 31u);  // header + at least 1 s of rows
    EXPECT_EQ(text.back(), '\n');
    // The recorder object dies without stop(): the file stays .partial.
  }
  ASSERT_TRUE(fs::exists(partial));
  EXPECT_EQ(fs::path(partial).extension(), ".partial");
  // Readable as it is ...
  const task::Demonstration d = task::readDemonstrationCsv(partial, c.spec);
  EXPECT_GE(d.rows(), 30u);
  // ... and reported by validation as a partial recording.
  const task::TaskDirReport report = task::checkTaskDir(dir.path.string());
  ASSERT_EQ(report.errors.size(), 1u);
  EXPECT_NE(report.errors[0].message.find("partial recording"), std::string::npos);
  // The next demonstration does not overwrite it.
  DemoRecorder rec(c.spec, dir.path.string(), 1.0);
  EXPECT_EQ(fs::path(rec.start(0.0)).filename(), "demo_001.csv");
  rec.discard();
}

namespace {

/// 12 entities: 8 robots, 3 objects (with label columns) and a goal.
task::TaskSpec twelveEntities() {
  task::TaskSpec spec;
  spec.name = "kill_test";
  for (int i = 0; i < 8; ++i)
    spec.entities.push_back({"R" + std::to_string(i + 1), task::EntityKind::Robot, "hamster"});
  for (int i = 0; i < 3; ++i) spec.entities.push_back({"O" + std::to_string(i + 1), task::EntityKind::Object, "box"});
  spec.entities.push_back({"G1", task::EntityKind::Goal, ""});
  spec.actions = {"move", "push"};
  spec.actions_declared = true;
  return spec;
}

struct KilledRecording {
  std::string partial;  ///< the .partial file it left
  long rows_added = 0;  ///< rows whose addRow() had returned before the kill
};

/// Forks a recorder writing rows of 12 entities (every `period_s`, 0 = as fast as
/// it can), SIGKILLs it `kill_after_s` after its first row; what it left.

KilledRecording recordAndKill(const std::string& dir, double period_s, double kill_after_s) {
  const task::TaskSpec spec = twelveEntities();
  int ready[2];
  if (::pipe(ready) != 0) throw Error("pipe failed");
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(ready[0]);
    try {
      DemoRecorder rec(spec, dir, 1.0);
      rec.start(0.0);
      rec.setLabel("R1", "move", "O2");
      rec.setLabel("O3", "push", "G1");
      std::vector<Eigen::Vector2d> p(spec.entities.size());
      for (long i = 0;; ++i) {
        const double t = i * (period_s > 0 ? period_s : 1e-3);
        for (size_t k = 0; k < p.size(); ++k) p[k] = {0.123456 + 0.001 * k + 0.1 * t, 0.654321 - 0.002 * k};
        rec.addRow(t, p);
        if (i == 0) {
          const std::string path = rec.partialPath() + "\n";
          if (::write(ready[1], path.data(), path.size()) < 0) ::_exit(3);
        }
        if (::write(ready[1], "r", 1) != 1) ::_exit(3);  // one byte per row added
        if (period_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
      }
    } catch (...) {
      ::_exit(2);
    }
  }
  ::close(ready[1]);
  KilledRecording out;
  char c;
  while (::read(ready[0], &c, 1) == 1 && c != '\n') out.partial += c;
  std::this_thread::sleep_for(std::chrono::duration<double>(kill_after_s));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the recorder died by itself: " << status;
  char buf[4096];
  for (ssize_t n; (n = ::read(ready[0], buf, sizeof buf)) > 0;) out.rows_added += n;  // EOF: the child is gone
  ::close(ready[0]);
  return out;
}

}  // namespace

TEST(Recorder, KillNineLeavesWholeRowsAtAnyKillPoint) {
  const task::TaskSpec spec = twelveEntities();
  // 30 Hz as the recorder runs (a 4 KiB stdio buffer fills twice a second with 12
  // entities), then as fast as it can write (kills land in the middle of writes).
  const std::vector<std::pair<double, double>> runs = {
      {1 / 30.0, 0.15}, {1 / 30.0, 0.55}, {1 / 30.0, 0.9}, {1 / 30.0, 1.35}, {1 / 30.0, 1.7},
      {0.0, 0.003},     {0.0, 0.011},     {0.0, 0.027},    {0.0, 0.05},      {0.0, 0.13}};
  for (const auto& [period, kill_after] : runs) {
    TempDir dir;
    const KilledRecording killed = recordAndKill(dir.path.string(), period, kill_after);
    const std::string& partial = killed.partial;
    ASSERT_FALSE(partial.empty()) << "the recorder did not start";
    ASSERT_TRUE(fs::exists(partial));
    // The documented recovery (`ddace recover`): the whole rows become the .csv, a row
    // torn by the kill (rarely: a write cut at a page boundary) is cut; the directory validates.
    const std::string text = readTextFile(partial);
    RecoveredRecording r;
    try {
      r = recoverPartialRecording(partial, spec);
    } catch (const Error& e) {
      ADD_FAILURE() << "killed after " << kill_after << " s: " << e.what();
      continue;
    }
    EXPECT_EQ(readTextFile(r.csv_path) + r.torn_row, text) << "only the torn last row is cut";
    EXPECT_EQ(r.torn_row.find('\n'), std::string::npos);
    const task::TaskDirReport report = task::checkTaskDir(dir.path.string());
    EXPECT_TRUE(report.errors.empty()) << "killed after " << kill_after
                                       << " s: " << (report.errors.empty() ? "" : report.errors[0].message);
    const task::Demonstration d = task::readDemonstrationCsv(r.csv_path, spec);
    EXPECT_EQ(d.rows(), r.rows);
    // Every row added before the kill is in the file (rows are not held back), however
    // fast the machine ran.
    EXPECT_GE(d.rows(), static_cast<size_t>(killed.rows_added)) << "killed after " << kill_after << " s";
    EXPECT_GT(killed.rows_added, 0);
  }
}

namespace {

/// A task directory with one recording left .partial (40 rows of the shipped task, R1
/// labelled); returns the .partial file's path and fills `text` with its bytes.
std::string leftPartial(const fs::path& dir, std::string& text) {
  const RecorderConfig c = shippedConfig();
  DemoRecorder rec(c.spec, dir.string(), 1.0);
  rec.start(0.0);
  rec.setLabel("R1", "move", "G1");
  for (int i = 0; i < 40; ++i) rec.addRow(i / 30.0, positions(i / 30.0));
  text = readTextFile(rec.partialPath());
  return rec.partialPath();
}

}  // namespace

// What a kill during a row's write(2) leaves, made exactly: the file cut inside, at the
// start and at the end of its last two rows (one lacking only its newline). The recovery
// keeps every whole row and cuts only the torn one.
TEST(Recorder, RecoveryKeepsEveryWholeRowAndCutsOnlyATornLastRow) {
  TempDir dir;
  std::string text;
  const std::string partial = leftPartial(dir.path, text);
  const task::TaskSpec spec = shippedConfig().spec;
  const size_t last = text.rfind('\n', text.size() - 2) + 1;  // the last row's start
  const size_t before_last = text.rfind('\n', last - 2) + 1;  // the row before it
  const size_t mid = (last + text.size()) / 2;
  for (size_t cut : {before_last + 1, last - 1, last, last + 1, mid, text.size() - 1, text.size()}) {
    writeTextFile(partial, text.substr(0, cut));
    const RecoveredRecording r = recoverPartialRecording(partial, spec);
    const size_t whole = text.rfind('\n', cut - 1) + 1;
    EXPECT_EQ(readTextFile(r.csv_path), text.substr(0, whole)) << "cut at " << cut;
    EXPECT_EQ(r.torn_row, text.substr(whole, cut - whole)) << "the torn row is shown as it was";
    EXPECT_EQ(r.rows, static_cast<size_t>(std::count(text.begin(), text.begin() + whole, '\n')) - 1);
    EXPECT_EQ(r.rows, cut == text.size() ? 40u : (cut >= last ? 39u : 38u));
    EXPECT_EQ(r.steps, 1u);
    EXPECT_FALSE(fs::exists(partial));
    EXPECT_TRUE(task::checkTaskDir(dir.path.string()).errors.empty()) << "cut at " << cut;
    fs::remove(r.csv_path);
  }
}

// A .partial file that cannot be kept is left exactly as it was, and no .csv is written.
TEST(Recorder, RecoveryLeavesWhatItCannotKeepAsItWas) {
  TempDir dir;
  std::string text;
  const std::string partial = leftPartial(dir.path, text);
  const std::string csv = partial.substr(0, partial.size() - std::string(".partial").size());
  const task::TaskSpec spec = shippedConfig().spec;
  const size_t header_end = text.find('\n') + 1;
  auto refused = [&](const std::string& bytes, const std::string& why) {
    writeTextFile(partial, bytes);
    try {
      recoverPartialRecording(partial, spec);
      ADD_FAILURE() << "kept: " << why;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(partial), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    EXPECT_EQ(readTextFile(partial), bytes);
    EXPECT_FALSE(fs::exists(csv));
  };
  refused("", "empty");
  refused(text.substr(0, header_end - 5), "no whole line");  // died in the first write
  refused(text.substr(0, header_end + 20), "no data rows");  // the first row torn
  std::string bad = text;
  bad[text.find('\n', header_end) + 1] = 'x';  // row 2's t (line 3)
  refused(bad, ":3:");
  writeTextFile(csv, "theirs");
  writeTextFile(partial, text);
  EXPECT_THROW(recoverPartialRecording(partial, spec), Error);  // never over another demonstration
  EXPECT_EQ(readTextFile(csv), "theirs");
  EXPECT_EQ(readTextFile(partial), text);
}

// The recovery as a user runs it: validate names the command, recover says what it cut.
TEST(Recorder, DdaceRecoverKeepsTheWholeRowsAndShowsTheTornOne) {
  TempDir dir;
  std::string text;
  const std::string partial = leftPartial(dir.path, text);
  const size_t last = text.rfind('\n', text.size() - 2) + 1;
  writeTextFile(partial, text.substr(0, last + 12));
  const std::string d = "'" + dir.path.string() + "'";
  const test::ToolRun before = test::runTool("validate " + d);
  EXPECT_EQ(before.status, 1);
  EXPECT_NE(before.out.find("partial recording"), std::string::npos) << before.out;
  EXPECT_NE(before.out.find("ddace recover " + dir.path.string()), std::string::npos) << before.out;
  const test::ToolRun run = test::runTool("recover " + d);
  EXPECT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("39 rows kept, labelled steps: 1"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("cut its torn last row (12 bytes without a newline"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find(text.substr(last, 12)), std::string::npos) << run.out;
  const test::ToolRun after = test::runTool("validate " + d);
  EXPECT_EQ(after.status, 0) << after.out;
  EXPECT_NE(test::runTool("recover " + d).out.find("nothing to recover"), std::string::npos);
}

TEST(Recorder, RefusesADirectoryOfAnotherTask) {
  TempDir dir;
  RecorderConfig c = shippedConfig();
  { DemoRecorder rec(c.spec, dir.path.string()); }
  c.spec.entities.pop_back();
  EXPECT_THROW(DemoRecorder(c.spec, dir.path.string()), Error);
}

TEST(Recorder, ARowNeedsEveryEntityMeasuredOnceAndCountsStalePoses) {
  const RecorderConfig c = shippedConfig();
  ASSERT_GE(c.spec.entities.size(), 2u);
  LatestPositions latest(c.spec);
  std::string all_names;
  for (const auto& e : c.spec.entities) all_names += (all_names.empty() ? "" : ", ") + e.name;
  EXPECT_FALSE(latest.all().has_value());
  EXPECT_EQ(latest.missing(), all_names);

  const std::string first = c.spec.entities[0].name;
  latest.update(first, {0.3, 0.4}, false, true, 0.0);
  latest.update(c.spec.entities[1].name, {0.9, 0.9}, true, false, 0.0);  // never measured: not a position
  latest.update("not_in_the_task", {0.5, 0.5}, false, true, 0.0);
  EXPECT_FALSE(latest.all().has_value());
  EXPECT_EQ(latest.missing().find(first), std::string::npos);
  EXPECT_NE(latest.missing().find(c.spec.entities[1].name), std::string::npos);

  for (size_t i = 1; i < c.spec.entities.size(); ++i)
    latest.update(c.spec.entities[i].name, {0.1 * static_cast<double>(i), 0.2}, false, true, 0.0);
  latest.update(first, {0.35, 0.45}, true, true, 0.0);  // held by the tracker: the latest pose, stale
  const auto p = latest.all();
  ASSERT_TRUE(p.has_value());
  ASSERT_EQ(p->size(), c.spec.entities.size());
  EXPECT_EQ((*p)[0], Eigen::Vector2d(0.35, 0.45));
  EXPECT_EQ((*p)[1], Eigen::Vector2d(0.1, 0.2));
  EXPECT_EQ(latest.missing(), "");
  EXPECT_EQ(latest.stale(), 1);
  latest.update(first, {0.36, 0.45}, false, true, 0.0);
  EXPECT_EQ(latest.stale(), 0);
}

// The first row of a demonstration is every entity's start: the recorder starts only once
// the scene has been at rest for the label inference's still_s (a robot still being placed
// would make the demonstration start with a motion, a goal being placed read as moved).
TEST(Recorder, TheSceneIsAtRestOnlyWhenNothingMovedForStillSeconds) {
  const RecorderConfig c = shippedConfig();
  LatestPositions latest(c.spec);
  const double still_s = latest.stillSeconds();
  ASSERT_GT(still_s, 0.0);
  auto all = [&](double t, double dx) {
    for (size_t i = 0; i < c.spec.entities.size(); ++i)
      latest.update(c.spec.entities[i].name, {0.1 * static_cast<double>(i) + (i == 0 ? dx : 0.0), 0.5}, false, true, t);
  };
  const std::string r1 = c.spec.entities[0].name;
  // Just seen: not known to be at rest yet, but nothing moved (nobody has to let go).
  all(0.0, 0.0);
  EXPECT_EQ(latest.moving(0.1), "");
  std::string everyone;
  for (const auto& e : c.spec.entities) everyone += (everyone.empty() ? "" : ", ") + e.name;
  EXPECT_EQ(latest.appeared(0.1), everyone);
  // At rest (tracker noise of a millimetre is no motion) for still_s: ready.
  for (double t = 0.0; t <= still_s + 0.05; t += 0.05) all(t, 0.001 * std::sin(40 * t));
  EXPECT_EQ(latest.moving(still_s + 0.05), "");
  EXPECT_EQ(latest.appeared(still_s + 0.05), "");
  // R1 is moved by a hand (2 cm): it is named, the others are not, until it rests again.
  double t = still_s + 0.1;
  for (int k = 0; k < 5; ++k, t += 0.05) all(t, 0.005 * k);
  EXPECT_EQ(latest.moving(t), r1);
  all(t + still_s / 2, 0.02);
  EXPECT_EQ(latest.moving(t + still_s / 2), r1);
  all(t + still_s + 0.01, 0.02);
  EXPECT_EQ(latest.moving(t + still_s + 0.01), "");
}

TEST(Recorder, HiddenEntitiesAreNamedWithWhetherToAct) {
  const RecorderConfig c = shippedConfig();
  LatestPositions latest(c.spec);
  size_t goal = 0, robot = 0;
  for (size_t i = 0; i < c.spec.entities.size(); ++i)
    (c.spec.entities[i].kind == ddace::task::EntityKind::Goal ? goal : robot) = i;
  const std::string g = c.spec.entities[goal].name, r = c.spec.entities[robot].name;
  auto row = [&](double t, bool goal_hidden, bool robot_hidden, double robot_x) {
    for (size_t i = 0; i < c.spec.entities.size(); ++i) {
      const bool hidden = (i == goal && goal_hidden) || (i == robot && robot_hidden);
      latest.update(c.spec.entities[i].name, {i == robot ? robot_x : 0.1 * static_cast<double>(i), 0.5}, hidden, true,
                    t);
    }
    latest.countRow();
  };
  row(0.0, false, false, 0.7);
  EXPECT_EQ(latest.staleRowsReport(), "");
  // The goal under a parked robot for 3 rows: named, harmless.
  for (int k = 1; k <= 3; ++k) row(0.1 * k, true, false, 0.7);
  row(0.4, false, false, 0.7);
  std::string report = latest.staleRowsReport();
  EXPECT_NE(report.find(g + " hidden in 3 rows"), std::string::npos) << report;
  EXPECT_NE(report.find("harmless"), std::string::npos) << report;
  EXPECT_EQ(report.find("ACT"), std::string::npos) << report;
  // The robot hidden under a hand while it was carried 10 cm: the user has to act.
  latest.resetRows();
  for (int k = 1; k <= 2; ++k) row(0.4 + 0.1 * k, false, true, 0.7);
  row(0.7, false, false, 0.8);
  report = latest.staleRowsReport();
  EXPECT_EQ(report.find(g + " hidden"), std::string::npos) << report;
  EXPECT_NE(report.find(r + " hidden in 2 rows"), std::string::npos) << report;
  EXPECT_NE(report.find("ACT"), std::string::npos) << report;
}

TEST(Recorder, InferredLabelsToCheckSayWhetherToActAndHow) {
  TempDir dir;
  const RecorderConfig c = shippedConfig();
  // R1 drives towards the middle and rests there, away from every entity, 5 s (the
  // labeller's pause_s is 3 s): "stopped halfway".
  const auto scene = [](double t, const Eigen::Vector2d& end) {
    std::vector<Eigen::Vector2d> p = positions(0);
    const double s = std::clamp((t - 1.0) / 1.5, 0.0, 1.0);
    p[0] = (1 - s) * p[0] + s * end;
    return p;
  };
  DemoRecorder rec(c.spec, dir.path.string(), 1.0);
  rec.inferLabels(true);
  const std::string path = rec.start(0.0);
  for (int i = 0; i < 30 * 8; ++i) rec.addRow(i / 30.0, scene(i / 30.0, {0.27, 0.5}));
  ASSERT_EQ(rec.stop(), path);
  ASSERT_FALSE(rec.inferenceNotes().empty());
  EXPECT_NE(rec.inferenceNotes().front().find("R1 stopped halfway"), std::string::npos) << rec.inferenceNotes().front();
  const std::string& advice = rec.inferenceAdvice();
  EXPECT_NE(advice.find("what to do: nothing, if every label taken above is what you demonstrated"), std::string::npos)
      << advice;
  EXPECT_NE(advice.find("scripts/label_keyboard.py --review " + path + "`, or delete that file"), std::string::npos)
      << advice;
  EXPECT_NE(advice.find("\"stopped halfway\": the robot rested 3 s or longer away from every entity"),
            std::string::npos)
      << advice;

  // R1 to G1 and nothing unsure: no advice either.
  rec.start(100.0);
  for (int i = 0; i < 30 * 8; ++i) rec.addRow(100.0 + i / 30.0, scene(i / 30.0, positions(0)[4]));
  rec.stop();
  EXPECT_TRUE(rec.inferenceNotes().empty()) << rec.inferenceNotes().front();
  EXPECT_EQ(rec.inferenceAdvice(), "");

  // Nothing moved (started and stopped at once): saved, and said to teach nothing.
  const std::string still = rec.start(200.0);
  for (int i = 0; i < 30 * 2; ++i) rec.addRow(200.0 + i / 30.0, positions(0));
  ASSERT_EQ(rec.stop(), still);
  EXPECT_EQ(rec.inferredSteps(), "none");
  EXPECT_NE(rec.inferenceAdvice().find("has no step and teaches nothing (ddace train refuses it): delete " + still),
            std::string::npos)
      << rec.inferenceAdvice();
}
