#include "ddace/vision/recorder.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <utility>

#include "ddace/common/file.h"
#include "ddace/label/inference.h"
#include "ddace/label/recording.h"
#include "ddace/task/summary.h"
#include "yaml_values.h"

namespace ddace::vision {

namespace fs = std::filesystem;
using detail::numberOr;
using detail::parseRoot;
using detail::stringOr;

RecorderConfig parseRecorderConfig(const std::string& text, const std::string& file, const MarkerConfig& markers) {
  YamlChecker r(file);
  RecorderConfig c;
  const YAML::Node root = parseRoot(r, text, "recorder.yaml");
  r.onlyKeys(root, {"output_dir", "rate_hz", "flush_period", "infer_labels", "example", "task"}, "recorder.yaml");
  c.output_dir = stringOr(r, root, "output_dir", "");
  if (c.output_dir.empty()) r.error(root, "'output_dir' (the task directory to record into) is required");
  if (c.output_dir.rfind("~/", 0) == 0) {
    const char* home = std::getenv("HOME");
    c.output_dir = std::string(home ? home : "") + c.output_dir.substr(1);
  }
  c.rate_hz = numberOr(r, root, "rate_hz", c.rate_hz, 0.1, 1000.0);
  if (const YAML::Node n = root["infer_labels"]; n.IsDefined()) {
    if (!n.IsScalar() || (n.Scalar() != "true" && n.Scalar() != "false"))
      r.error(n, "'infer_labels' must be true or false");
    else c.infer_labels = n.Scalar() == "true";
  }
  c.example = stringOr(r, root, "example", "");
  c.flush_period_s = numberOr(r, root, "flush_period", c.flush_period_s, 0.01, 1.0);

  for (const auto& m : markers.entities) c.spec.entities.push_back({m.name, m.kind, m.type});
  const YAML::Node t = root["task"];
  if (!t.IsDefined() || !r.expectMap(t, "'task'")) {
    if (!t.IsDefined()) r.error(root, "'task' (name, actions, goal conditions of the recorded task) is required");
  } else {
    r.onlyKeys(t, {"name", "actions", "arrival_radius", "goal_conditions"}, "'task'");
    c.spec.name = stringOr(r, t, "name", "");
    if (c.spec.name.empty()) r.error(t, "'task.name' is required");
    c.spec.arrival_radius = numberOr(r, t, "arrival_radius", task::kDefaultArrivalRadius, 1e-4, 10.0);
    if (const YAML::Node a = t["actions"]; a.IsDefined()) {
      if (!a.IsSequence()) {
        r.error(a, "'actions' must be a list of words");
      } else {
        c.spec.actions_declared = true;
        for (const auto& w : a) {
          const std::string word = w.IsScalar() ? w.Scalar() : "";
          if (!task::isValidName(word) || word == "idle")
            r.error(w, "action '" + word + "' must match [A-Za-z][A-Za-z0-9_]* and not be 'idle'");
          else c.spec.actions.push_back(word);
        }
      }
    }
    if (const YAML::Node g = t["goal_conditions"]; g.IsDefined()) {
      if (!g.IsSequence()) {
        r.error(g, "'goal_conditions' must be a list of {entity, at, tolerance}");
      } else {
        for (const auto& gc : g) {
          if (!r.expectMap(gc, "a goal condition")) continue;
          r.onlyKeys(gc, {"entity", "at", "tolerance"}, "a goal condition");
          task::GoalCondition cond;
          cond.entity = stringOr(r, gc, "entity", "");
          cond.at = stringOr(r, gc, "at", "");
          cond.tolerance = numberOr(r, gc, "tolerance", cond.tolerance, 0.0, 10.0);
          if (!(cond.tolerance > 0))  // as task.yaml's reader (found by fuzzing: 0 was accepted)
            r.error(gc["tolerance"], "tolerance must be positive (metres)");
          for (const auto* name : {&cond.entity, &cond.at})
            if (c.spec.entityIndex(*name) < 0)
              r.error(gc, "goal condition names '" + *name + "', which is not an entity of markers.yaml");
          c.spec.goal_conditions.push_back(cond);
        }
      }
    }
  }
  r.throwIfErrors();
  // The recorder writes this task into every task directory it records: a task that the
  // task module's own reader would refuse is refused here, before anything is recorded.
  try {
    task::parseTaskYaml(task::taskYamlText(c.spec), "task.yaml");
  } catch (const Error& e) {
    throw Error(Diagnostic{file, 0, 0, std::string("the task.yaml it would write is refused: ") + e.what()});
  }
  return c;
}

RecorderConfig loadRecorderConfig(const std::string& path, const MarkerConfig& markers) {
  return parseRecorderConfig(readTextFile(path), path, markers);
}

DemoRecorder::DemoRecorder(task::TaskSpec spec, std::string task_dir, double flush_period_s)
    : spec_(std::move(spec)), dir_(std::move(task_dir)), flush_period_s_(flush_period_s) {
  labels_.assign(spec_.entities.size(), task::Label{});
  std::error_code ec;
  fs::create_directories(fs::path(dir_) / "demos", ec);
  if (ec) throw Error(Diagnostic{dir_, 0, 0, "cannot create the task directory: " + ec.message()});
  const fs::path yaml = fs::path(dir_) / "task.yaml";
  const std::string mine = task::taskYamlText(spec_);
  if (fs::exists(yaml)) {
    // More demonstrations of the same task go next to the others; a different scene
    // would make the directory unusable.
    const task::TaskSpec theirs = task::readTaskYaml(yaml.string());
    if (task::taskYamlText(theirs) != mine)
      throw Error(Diagnostic{yaml.string(), 0, 0,
                             "this task.yaml differs from the recorder's configuration (markers.yaml + "
                             "recorder.yaml); record into another directory or fix the configuration"});
  } else {
    task::writeTaskYaml(spec_, yaml.string());
  }
}

DemoRecorder::~DemoRecorder() {
  // Leave an interrupted recording as it is: whole rows, still .partial.
  closeFile();
}

void DemoRecorder::closeFile() {
  if (fd_ < 0) return;
  ::fdatasync(fd_);
  ::close(fd_);
  fd_ = -1;
}

void DemoRecorder::writeWhole(const std::string& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw Error(Diagnostic{partial_path_, 0, 0, std::string("cannot write: ") + std::strerror(errno)});
    done += static_cast<size_t>(n);  // a short write to a file only happens when the disk is full
  }
}

std::string DemoRecorder::start(double t0) {
  if (fd_ >= 0) throw Error("already recording " + final_path_ + " (stop or discard it first)");
  int next = 0;
  const std::regex pattern(R"(demo_(\d+)\.csv(\.partial)?)");
  for (const auto& entry : fs::directory_iterator(fs::path(dir_) / "demos")) {
    std::smatch m;
    const std::string name = entry.path().filename().string();
    if (std::regex_match(name, m, pattern)) next = std::max(next, std::stoi(m[1]) + 1);
  }
  char name[32];
  std::snprintf(name, sizeof name, "demo_%03d.csv", next);
  final_path_ = (fs::path(dir_) / "demos" / name).string();
  partial_path_ = final_path_ + ".partial";
  fd_ = ::open(partial_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) throw Error(Diagnostic{partial_path_, 0, 0, std::string("cannot create: ") + std::strerror(errno)});
  std::string header = "t";
  for (size_t i = 0; i < spec_.entities.size(); ++i) {
    const std::string& n = spec_.entities[i].name;
    header += "," + n + ".x," + n + ".y";
    if (hasLabelColumns(i)) header += "," + n + ".action," + n + ".target";
  }
  header += "\n";
  header_ = header;
  clearLabels();
  labelled_ = false;
  inferred_steps_.clear();
  notes_.clear();
  advice_.clear();
  t0_ = t0;
  last_t_ = -1;
  last_flush_ = 0;
  rows_ = 0;
  return final_path_;
}

void DemoRecorder::setLabel(const std::string& entity, const std::string& action_in, const std::string& target) {
  const int e = spec_.entityIndex(entity);
  if (e < 0) throw Error("unknown entity '" + entity + "'");
  if (!hasLabelColumns(static_cast<size_t>(e))) throw Error("'" + entity + "' is a goal: goals take no labels");
  const std::string action = action_in == "idle" ? "" : action_in;
  task::Label l;
  if (action.empty()) {
    if (!target.empty()) throw Error("a target ('" + target + "') needs an action");
  } else {
    if (!task::isValidName(action)) throw Error("action '" + action + "' must match [A-Za-z][A-Za-z0-9_]*");
    if (!spec_.allowsAction(action)) {
      std::string list;
      for (const auto& a : spec_.actions) list += (list.empty() ? "" : ", ") + a;
      throw Error("action '" + action + "' is not in the task's vocabulary (" + list + ")");
    }
    l.action = action;
    if (!target.empty()) {
      l.target = spec_.entityIndex(target);
      if (l.target < 0) throw Error("unknown target '" + target + "'");
      if (l.target == e) throw Error("'" + entity + "' cannot target itself");
    }
  }
  labels_[static_cast<size_t>(e)] = l;
  labelled_ = labelled_ || !l.isNull();
}

void DemoRecorder::inferLabels(bool on, std::optional<label::Example> example) {
  infer_ = on;
  example_ = std::move(example);
}

void DemoRecorder::clearLabels() {
  labels_.assign(spec_.entities.size(), task::Label{});
}

bool DemoRecorder::addRow(double t_abs, const std::vector<Eigen::Vector2d>& positions) {
  if (fd_ < 0) throw Error("not recording");
  if (positions.size() != spec_.entities.size())
    throw Error("a row needs " + std::to_string(spec_.entities.size()) + " positions, got " +
                std::to_string(positions.size()));
  const double t = t_abs - t0_;
  if (rows_ > 0 && !(t > last_t_ + 5e-7)) return false;  // t must increase at the CSV's precision
  for (const auto& p : positions)
    if (!std::isfinite(p.x()) || !std::isfinite(p.y())) throw Error("a position is not a finite number");
  std::string row = std::exchange(header_, {});
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", std::max(0.0, t));
  row += buf;
  for (size_t i = 0; i < positions.size(); ++i) {
    std::snprintf(buf, sizeof buf, ",%.6f,%.6f", positions[i].x(), positions[i].y());
    row += buf;
    if (hasLabelColumns(i)) {
      const task::Label& l = labels_[i];
      row += "," + l.action + "," + (l.target >= 0 ? spec_.entities[static_cast<size_t>(l.target)].name : "");
    }
  }
  row += "\n";
  // One write(2) per row, nothing held back: a killed recorder leaves every row added
  // (stdio would hold rows back and hand over 4 KiB blocks cut anywhere). A kill during
  // the write can still tear this row at a page boundary: recoverPartialRecording cuts it.
  writeWhole(row);
  last_t_ = std::max(0.0, t);
  ++rows_;
  if (last_t_ - last_flush_ >= flush_period_s_) {
    flush();
    last_flush_ = last_t_;
  }
  return true;
}

void DemoRecorder::flush() {
  if (fd_ >= 0) ::fdatasync(fd_);
}

std::string DemoRecorder::reviewAdvice(const label::Inference& inf, const std::string& path) const {
  std::string advice =
      "what to do: nothing, if every label taken above is what you demonstrated (the demonstration is used as it "
      "is); else correct it with `scripts/label_keyboard.py --review " +
      path + "`, or delete that file and demonstrate again";
  const bool halfway = std::any_of(inf.notes.begin(), inf.notes.end(), [](const label::Note& n) {
    return n.message.find(" stopped halfway: ") != std::string::npos;
  });
  if (halfway) {
    std::ostringstream pause;
    pause << label::SegmentationOptions::forTask(spec_).pause_s;
    advice += "\n\"stopped halfway\": the robot rested " + pause.str() +
              " s or longer away from every entity, so its motion ended there; if it was on its way to another "
              "entity, demonstrate again without resting on the way";
  }
  return advice;
}

std::string DemoRecorder::stop() {
  if (fd_ < 0) throw Error("not recording");
  closeFile();
  if (rows_ == 0)
    throw Error(Diagnostic{partial_path_, 0, 0, "no rows were recorded (no entity poses arrived?); file left as is"});
  const task::DemonstrationSummary recorded =
      task::summarizeDemonstrationCsv(partial_path_, spec_);  // file:line:column
  if (infer_ && !labelled_ && recorded.steps.empty()) {
    // The labelled copy is written beside the recording and checked before it replaces it.
    const label::Inference inf = label::inferRecording(partial_path_, spec_, example_ ? &*example_ : nullptr);
    {
      OutputFile out(final_path_);
      label::writeLabelledRecording(partial_path_, spec_, inf, out.stream());
      out.commit();
    }
    task::summarizeDemonstrationCsv(final_path_, spec_);
    const std::string shown = "demos/" + fs::path(final_path_).filename().string();
    for (const auto& st : inf.steps) {
      inferred_steps_ += inferred_steps_.empty() ? "[" : " [";
      for (size_t i = 0; i < st.tokens.size(); ++i)
        inferred_steps_ += (i ? " " : "") + task::tokenKey(st.tokens[i].token, spec_);
      inferred_steps_ += "]";
    }
    for (const auto& n : inf.notes) notes_.push_back(shown + ":" + std::to_string(n.row + 2) + ": " + n.message);
    if (!notes_.empty()) advice_ = reviewAdvice(inf, final_path_);
    if (inf.steps.empty()) {
      inferred_steps_ = "none";
      advice_ =
          "what to do: no robot moved to an entity, so this demonstration has no step and teaches nothing "
          "(ddace train refuses it): delete " +
          final_path_ + " and demonstrate again";
    }
    std::error_code ec;
    fs::remove(partial_path_, ec);
    return final_path_;
  }
  std::error_code ec;
  fs::rename(partial_path_, final_path_, ec);
  if (ec) throw Error(Diagnostic{partial_path_, 0, 0, "cannot rename to " + final_path_ + ": " + ec.message()});
  return final_path_;
}

namespace {

/// The offset just after the last newline of the `size` bytes of `path` (0 when there is
/// none), read from its end: a file of any length.
std::uintmax_t endOfWholeLines(const std::string& path, std::uintmax_t size) {
  std::ifstream in(path, std::ios::binary);
  char buf[4096];
  for (std::uintmax_t end = size; end > 0;) {
    const std::uintmax_t n = std::min<std::uintmax_t>(sizeof buf, end);
    in.seekg(static_cast<std::streamoff>(end - n));
    in.read(buf, static_cast<std::streamsize>(n));
    if (!in) throw Error(Diagnostic{path, 0, 0, "cannot read: " + std::string(std::strerror(errno))});
    for (std::uintmax_t i = n; i-- > 0;)
      if (buf[i] == '\n') return end - n + i + 1;
    end -= n;
  }
  return 0;
}

/// Copies the first `bytes` bytes of `from` to `to` (written whole or not at all).
void copyPrefix(const std::string& from, std::uintmax_t bytes, const std::string& to) {
  std::ifstream in(from, std::ios::binary);
  OutputFile out(to);
  char buf[1 << 16];
  for (std::uintmax_t left = bytes; left > 0;) {
    const std::uintmax_t n = std::min<std::uintmax_t>(sizeof buf, left);
    in.read(buf, static_cast<std::streamsize>(n));
    if (!in) throw Error(Diagnostic{from, 0, 0, "cannot read: " + std::string(std::strerror(errno))});
    out.write(std::string_view(buf, n));
    left -= n;
  }
  out.commit();
}

}  // namespace

RecoveredRecording recoverPartialRecording(const std::string& partial, const task::TaskSpec& spec) {
  const std::string suffix = ".csv.partial";
  if (partial.size() <= suffix.size() || partial.compare(partial.size() - suffix.size(), suffix.size(), suffix) != 0)
    throw Error(Diagnostic{partial, 0, 0, "not a recorder's partial recording (demos/NAME.csv.partial)"});
  RecoveredRecording r;
  r.csv_path = partial.substr(0, partial.size() - std::string(".partial").size());
  std::error_code ec;
  if (fs::exists(r.csv_path, ec) || ec)
    throw Error(
        Diagnostic{partial, 0, 0, r.csv_path + " exists already; rename one of the two (the next free demo_NNN.csv)"});
  const std::uintmax_t size = fs::file_size(partial, ec);
  if (ec) throw Error(Diagnostic{partial, 0, 0, "cannot read: " + ec.message()});
  const std::uintmax_t whole = endOfWholeLines(partial, size);
  if (whole == 0)
    throw Error(Diagnostic{partial, 1, 0,
                           size == 0 ? "empty: the recorder died before its first row; nothing to keep, delete it"
                                     : "no whole line: the recorder died while writing its first row; nothing to "
                                       "keep, delete it"});
  {
    std::ifstream in(partial, std::ios::binary);
    r.torn_row.resize(static_cast<size_t>(size - whole));
    in.seekg(static_cast<std::streamoff>(whole));
    in.read(r.torn_row.data(), static_cast<std::streamsize>(r.torn_row.size()));
    if (!in) throw Error(Diagnostic{partial, 0, 0, "cannot read: " + std::string(std::strerror(errno))});
  }
  copyPrefix(partial, whole, r.csv_path);
  try {
    const task::DemonstrationSummary kept = task::summarizeDemonstrationCsv(r.csv_path, spec);
    r.rows = kept.rows;
    r.steps = kept.step_count;
  } catch (const Error& e) {
    fs::remove(r.csv_path, ec);
    std::vector<Diagnostic> errors = e.diagnostics();
    for (auto& d : errors)
      if (d.file == r.csv_path) d.file = partial;  // its lines are the .partial file's lines
    throw Error(errors);
  }
  fs::remove(partial, ec);
  if (ec) throw Error(Diagnostic{partial, 0, 0, "kept as " + r.csv_path + " but cannot delete it: " + ec.message()});
  return r;
}

void DemoRecorder::discard() {
  if (fd_ < 0) throw Error("not recording");
  ::close(fd_);
  fd_ = -1;
  std::error_code ec;
  fs::remove(partial_path_, ec);
  rows_ = 0;
}

LatestPositions::LatestPositions(const task::TaskSpec& spec)
    : positions_(spec.entities.size()),
      stale_(spec.entities.size(), false),
      rest_(spec.entities.size(), Eigen::Vector2d::Zero()),
      rest_since_(spec.entities.size(), 0.0),
      first_seen_(spec.entities.size(), 0.0),
      stale_rows_(spec.entities.size(), 0),
      moved_hidden_(spec.entities.size(), false) {
  for (const auto& e : spec.entities) {
    names_.push_back(e.name);
    kinds_.push_back(e.kind);
  }
  const label::SegmentationOptions o = label::SegmentationOptions::forTask(spec);
  still_m_ = o.still_m;
  still_s_ = o.still_s;
  start_m_ = o.start_m;
}

void LatestPositions::update(const std::string& name, const Eigen::Vector2d& position_m, bool stale, bool measured,
                             double t) {
  if (!measured) return;
  const auto it = std::find(names_.begin(), names_.end(), name);
  if (it == names_.end()) return;
  const size_t i = static_cast<size_t>(it - names_.begin());
  if (!positions_[i]) first_seen_[i] = t;
  if (!positions_[i] || (position_m - rest_[i]).norm() > still_m_) {
    rest_[i] = position_m;
    rest_since_[i] = t;
  }
  if (positions_[i] && stale_[i] && !stale && (position_m - *positions_[i]).norm() > start_m_) moved_hidden_[i] = true;
  positions_[i] = position_m;
  stale_[i] = stale;
}

std::optional<std::vector<Eigen::Vector2d>> LatestPositions::all() const {
  std::vector<Eigen::Vector2d> out;
  for (const auto& p : positions_) {
    if (!p) return std::nullopt;
    out.push_back(*p);
  }
  return out;
}

std::string LatestPositions::missing() const {
  std::string out;
  for (size_t i = 0; i < names_.size(); ++i)
    if (!positions_[i]) out += (out.empty() ? "" : ", ") + names_[i];
  return out;
}

std::string LatestPositions::moving(double t) const {
  std::string out;
  for (size_t i = 0; i < names_.size(); ++i)
    if (positions_[i] && t - rest_since_[i] < still_s_ && t - first_seen_[i] >= still_s_)
      out += (out.empty() ? "" : ", ") + names_[i];
  return out;
}

std::string LatestPositions::appeared(double t) const {
  std::string out;
  for (size_t i = 0; i < names_.size(); ++i)
    if (positions_[i] && t - first_seen_[i] < still_s_) out += (out.empty() ? "" : ", ") + names_[i];
  return out;
}

int LatestPositions::stale() const {
  int n = 0;
  for (size_t i = 0; i < names_.size(); ++i) n += positions_[i] && stale_[i];
  return n;
}

void LatestPositions::countRow() {
  for (size_t i = 0; i < names_.size(); ++i) stale_rows_[i] += positions_[i] && stale_[i];
}

void LatestPositions::resetRows() {
  std::fill(stale_rows_.begin(), stale_rows_.end(), 0);
  std::fill(moved_hidden_.begin(), moved_hidden_.end(), false);
}

std::string LatestPositions::staleRowsReport() const {
  std::string out;
  for (size_t i = 0; i < names_.size(); ++i) {
    if (stale_rows_[i] == 0) continue;
    out += (out.empty() ? "" : "; ") + names_[i] + " hidden in " + std::to_string(stale_rows_[i]) +
           " rows (its last seen position recorded): ";
    if (moved_hidden_[i])
      out +=
          "ACT: it reappeared elsewhere, so it moved unseen and its path jumps; record this "
          "demonstration again with its marker in view (or discard it)";
    else if (kinds_[i] == task::EntityKind::Goal)
      out += "harmless, a goal does not move (e.g. one under a parked robot)";
    else if (stale_[i])
      out +=
          "CHECK: still hidden at the end; if it moved unseen, its recorded end is wrong (record again with "
          "its marker in view)";
    else out += "harmless, it reappeared where it was hidden";
  }
  return out;
}

}  // namespace ddace::vision
