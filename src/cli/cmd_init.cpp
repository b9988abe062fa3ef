// ddace init: a new task of one's own — task.yaml and the recorder, marker and Hamster
// configurations for exactly the entities named, commented where the lab fills in.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <set>
#include <sstream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/hamster/config.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/recorder.h"
#include "ddace/vision/tracker.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

struct InitEntities {
  std::vector<std::string> robots, objects, goals;
};

/// "R1,R2" -> {R1, R2}; every name checked as task.yaml checks it, none twice.
std::vector<std::string> splitNames(const std::string& list, const std::string& flag, std::set<std::string>& seen) {
  std::vector<std::string> names;
  std::stringstream in(list);
  for (std::string name; std::getline(in, name, ',');) {
    if (!task::isValidName(name)) throw Error(flag + ": '" + name + "' is not an entity name ([A-Za-z][A-Za-z0-9_]*)");
    if (!seen.insert(name).second) throw Error(flag + ": '" + name + "' is named twice");
    names.push_back(name);
  }
  return names;
}

/// A YAML double-quoted scalar (a path may hold ':' or '#').
std::string quoted(const std::string& s) {
  std::string q = "\"";
  for (char ch : s) q += (ch == '"' || ch == '\\') ? std::string("\\") + ch : std::string(1, ch);
  return q + "\"";
}

// Marker ids: the corners 0-3 (as config/markers.yaml), robots from 10, goals from 20,
// objects from 30 (DICT_4X4_50 has ids 0..49).
std::string markersYaml(const InitEntities& e) {
  std::ostringstream y;
  y << "# Fiducial markers of this task (tracker_node, recorder_node, synthetic_camera_node).\n"
       "# Every key is explained in the ddace package's config/markers.yaml (docs/vision.md).\n"
       "# FILL IN: the ids printed on your markers, and the corner marker centres measured on your\n"
       "# table (metres). The names are the task's: keep them as in task.yaml.\n"
       "backend: aruco\n"
       "family: DICT_4X4_50\n"
       "corners:                     # the table frame: four markers lying flat at known positions\n"
       "  - {id: 0, x: 0.0, y: 0.0}\n"
       "  - {id: 1, x: 1.0, y: 0.0}\n"
       "  - {id: 2, x: 1.0, y: 1.0}\n"
       "  - {id: 3, x: 0.0, y: 1.0}\n"
       "corner_size: 0.04\n"
       "default_size: 0.03\n"
       "default_height: 0.035        # a Hamster is about 3.5 cm tall; its marker sits on top\n"
       "entities:\n";
  int id = 10;
  for (const auto& r : e.robots) y << "  - {id: " << id++ << ", name: " << r << ", kind: robot, type: hamster}\n";
  id = 20;
  for (const auto& g : e.goals)
    y << "  - {id: " << id++ << ", name: " << g << ", kind: goal, size: 0.04, height: 0.0}   # flat on the table\n";
  id = 30;
  for (const auto& o : e.objects)
    y << "  - {id: " << id++ << ", name: " << o << ", kind: object, height: 0.03}   # FILL IN: its marker's height\n";
  return y.str();
}

std::string recorderYaml(const InitEntities& e, const std::string& name, const std::string& dir,
                         const std::vector<std::string>& actions) {
  std::ostringstream y;
  y << "# Demonstration recorder of this task (recorder_node). Every key is explained in the ddace\n"
       "# package's config/recorder.yaml. The entities come from markers.yaml next to this file.\n"
       "# `ddace init` wrote task.yaml from this file: when you change `task:` before the first\n"
       "# recording, delete task.yaml (the recorder writes it again from here).\n"
    << "output_dir: " << quoted(dir) << "\n"
    << "rate_hz: 30\n"
       "flush_period: 1.0\n"
       "infer_labels: true           # labels inferred when a demonstration is stopped: no `ddace label` needed\n"
       "task:\n"
    << "  name: " << quoted(name) << "\n";
  if (!actions.empty()) {
    y << "  actions: [";
    for (size_t i = 0; i < actions.size(); ++i) y << (i ? ", " : "") << actions[i];
    y << "]\n";
  } else {
    y << "  # actions: [move]         # the label vocabulary; without it, the words the demonstrations use\n";
  }
  y << "  arrival_radius: 0.03\n"
       "  # goal_conditions: what must hold at the end of a run (checked by the execution monitor).\n"
       "  # None is set: write your own, e.g.\n";
  const std::string mover = !e.objects.empty() ? e.objects.front() : e.robots.front();
  const std::string at = !e.goals.empty() ? e.goals.front() : "GOAL";
  y << "  # goal_conditions:\n"
    << "  #   - {entity: " << mover << ", at: " << at << ", tolerance: 0.05}\n";
  return y.str();
}

std::string hamstersYaml(const InitEntities& e) {
  std::ostringstream y;
  y << "# The Hamster robots of this task (hamster_bridge_node, calibrate_hamster.py). Every key is\n"
       "# explained in the ddace package's config/hamsters.yaml (docs/hamster.md).\n"
       "# FILL IN: each robot's radio address (`ddace hamster-scan` lists them; the bridge also warns\n"
       "# with the address of every robot it finds that is not here). The addresses below belong\n"
       "# to no robot: the bridge drives nothing until they are replaced by real ones.\n"
       "# The calibration is a first guess: measure it with\n"
       "#   rosrun ddace calibrate_hamster.py _robot:=NAME   (with the tracker running)\n"
       "port_dir: /dev\n"
       "scan: [serial/by-id/*, ttyUSB*, ttyACM*]\n"
       "rtscts: true\n"
       "command_timeout_s: 0.2\n"
       "link_timeout_s: 0.25\n"
       "robots:\n";
  int n = 1;
  for (const auto& r : e.robots) {
    char address[32];
    std::snprintf(address, sizeof address, "00:00:00:00:00:%02X", n++);
    y << "  - name: " << r << "\n"
      << "    address: \"" << address << "\"   # FILL IN\n"
      << "    model: auto\n"
      << "    calibration: {mps_per_unit: 0.0015, max_units: 100, track_m: 0.033}   # FILL IN (measured)\n";
  }
  return y.str();
}

int runInit(const std::vector<std::string>& argv) {
  Args args(argv, {"--robots", "--objects", "--goals", "--name", "--actions"});
  args.expectAtMostPositional(1);
  fs::path dir = fs::absolute(args.positional(0, "DIR (the new task directory)")).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();  // "DIR/"
  std::set<std::string> seen;
  InitEntities e;
  e.robots = splitNames(args.require("--robots"), "--robots", seen);
  if (args.has("--objects")) e.objects = splitNames(args.get("--objects", ""), "--objects", seen);
  if (args.has("--goals")) e.goals = splitNames(args.get("--goals", ""), "--goals", seen);
  std::set<std::string> no_names;
  const std::vector<std::string> actions =
      args.has("--actions") ? splitNames(args.get("--actions", ""), "--actions", no_names) : std::vector<std::string>{};
  const std::string name = args.get("--name", dir.filename().string());
  if (name.empty() || name.find('\n') != std::string::npos) throw Error("--name: give a name on one line");

  const fs::path config = dir / "config";
  const fs::path markers = config / "markers.yaml", recorder = config / "recorder.yaml",
                 hamsters = config / "hamsters.yaml", task_yaml = dir / "task.yaml";
  std::vector<Diagnostic> existing;
  for (const auto& f : {task_yaml, markers, recorder, hamsters})
    if (fs::exists(fs::symlink_status(f)))
      existing.push_back({f.string(), 0, 0, "exists: ddace init never replaces a file (choose another DIR)"});
  if (!existing.empty()) throw Error(existing);

  // Every file is read back with the reader that will read it, before anything is written.
  const std::string markers_text = markersYaml(e), recorder_text = recorderYaml(e, name, dir.string(), actions),
                    hamsters_text = hamstersYaml(e);
  const vision::MarkerConfig marker_config = vision::parseMarkerConfig(markers_text, markers.string());
  const vision::RecorderConfig recorder_config =
      vision::parseRecorderConfig(recorder_text, recorder.string(), marker_config);
  hamster::parseBridgeConfig(hamsters_text, hamsters.string());

  fs::create_directories(dir / "demos");
  fs::create_directories(config);
  writeTextFile(markers.string(), markers_text);
  writeTextFile(recorder.string(), recorder_text);
  writeTextFile(hamsters.string(), hamsters_text);
  task::writeTaskYaml(recorder_config.spec, task_yaml.string());

  const std::string c = config.string();
  const auto count = [](size_t n, const std::string& what) {
    return std::to_string(n) + " " + what + (n == 1 ? "" : "s");
  };
  std::cout << "ddace init: task '" << name << "' in " << dir.string() << ": " << count(e.robots.size(), "robot")
            << ", " << count(e.objects.size(), "object") << ", " << count(e.goals.size(), "goal")
            << ", no goal condition\n"
            << "  " << task_yaml.string() << "\n  " << (dir / "demos").string() << "/  (the demonstrations)\n  "
            << markers.string() << "   FILL IN: marker ids, corner positions\n"
            << "  " << recorder.string() << "  (goal conditions: write your own)\n"
            << "  " << hamsters.string() << "  FILL IN: radio addresses, calibration\n"
            << "next (README, \"Your own task\"):\n"
            << "  scripts/launch record.launch markers:=" << c << "/markers.yaml recorder:=" << c
            << "/recorder.yaml   (sim:=true: on a simulated table)\n"
            << "  ddace validate " << dir.string() << "\n";
  return 0;
}

DDACE_COMMAND({"init", "ddace init DIR --robots R1,R2 [--objects B1] [--goals G1] [--name NAME] [--actions move,push]",
               "start a task of your own: DIR/task.yaml, DIR/demos/ and DIR/config/{markers,recorder,hamsters}.yaml "
               "for exactly these entities (commented; marker ids, corner positions and radio addresses to fill in; "
               "no goal condition). Never replaces a file",
               runInit});

}  // namespace
}  // namespace ddace::cli
