#include "ddace/task/demonstration.h"
#include "ddace/task/summary.h"

#include <algorithm>
#include <limits>
#include <optional>
#include <cstdio>
#include <map>
#include <sstream>
#include <string_view>

#include "ddace/common/file.h"
#include "number.h"

namespace ddace::task {

bool Token::operator<(const Token& o) const {
  if (entity != o.entity) return entity < o.entity;
  if (action != o.action) return action < o.action;
  return target < o.target;
}

bool sameSteps(const std::vector<Step>& a, const std::vector<Step>& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(),
                    [](const Step& x, const Step& y) { return x.tokens == y.tokens; });
}

CommonSteps commonSteps(const std::vector<std::vector<Step>>& steps_of) {
  CommonSteps out;
  if (steps_of.empty()) return out;
  // The most common sequence (the first of the most common, in demonstration order).
  size_t modal = 0, modal_count = 0;
  for (size_t i = 0; i < steps_of.size(); ++i) {
    const size_t count = static_cast<size_t>(
        std::count_if(steps_of.begin(), steps_of.end(), [&](const auto& s) { return sameSteps(s, steps_of[i]); }));
    if (count > modal_count) modal = i, modal_count = count;
  }
  out.steps = steps_of[modal];
  // A slip: the same steps and tokens but one, which names the same entity.
  const auto slipOf = [&](size_t d) -> std::optional<StepSlip> {
    const std::vector<Step>& s = steps_of[d];
    if (s.size() != out.steps.size()) return std::nullopt;
    std::optional<StepSlip> slip;
    for (size_t k = 0; k < s.size(); ++k) {
      const auto& a = s[k].tokens;
      const auto& b = out.steps[k].tokens;
      if (a.size() != b.size()) return std::nullopt;
      for (size_t t = 0; t < a.size(); ++t) {
        if (a[t] == b[t]) continue;
        if (slip || a[t].entity != b[t].entity) return std::nullopt;
        slip = StepSlip{d, k, a[t], b[t]};
      }
    }
    return slip;
  };
  const size_t allowed = steps_of.size() / 10;
  for (size_t d = 0; d < steps_of.size(); ++d) {
    if (sameSteps(steps_of[d], out.steps)) continue;
    const std::optional<StepSlip> slip = slipOf(d);
    if (!slip || out.slips.size() == allowed) {
      out.slips.clear();
      return out;
    }
    out.slips.push_back(*slip);
  }
  out.fixed = true;
  return out;
}

std::string tokenKey(const Token& token, const TaskSpec& spec) {
  auto name = [&](int i) {
    return i >= 0 && i < static_cast<int>(spec.entities.size()) ? spec.entities[i].name : "#" + std::to_string(i);
  };
  std::string key = name(token.entity) + ":" + token.action;
  if (token.target >= 0) key += ":" + name(token.target);
  return key;
}

Token parseTokenKey(const std::string& key, const TaskSpec& spec) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(key);
  while (std::getline(in, part, ':')) parts.push_back(part);
  if (parts.size() < 2 || parts.size() > 3)
    throw Error("token '" + key + "' must be ENTITY:ACTION or ENTITY:ACTION:TARGET");
  Token t;
  t.entity = spec.entityIndex(parts[0]);
  if (t.entity < 0) throw Error("token '" + key + "': unknown entity '" + parts[0] + "'");
  t.action = parts[1];
  if (!isValidName(t.action) || t.action == "idle")
    throw Error("token '" + key + "': '" + t.action + "' is not an action");
  if (!spec.allowsAction(t.action))
    throw Error("token '" + key + "': action '" + t.action + "' is not in the task's actions");
  if (parts.size() == 3) {
    t.target = spec.entityIndex(parts[2]);
    if (t.target < 0) throw Error("token '" + key + "': unknown target '" + parts[2] + "'");
    if (t.target == t.entity) throw Error("token '" + key + "': an entity cannot target itself");
  }
  return t;
}

namespace {

/// Step grouping one row at a time (docs/task-format.md, "Step grouping"), with state for
/// the open step and each entity's running token only: analyze() over stored rows, and
/// the summary reader, which keeps no rows, compute the same steps.
class StepGrouper {
 public:
  /// `keep` false: only the open step is kept (its predecessors, their segments and
  /// snapshots are counted, not stored), for a summary in memory independent of the steps.
  explicit StepGrouper(size_t entities, bool keep = true) : prev_(entities), running_(entities), keep_(keep) {}

  void row(int i, double t, const std::vector<Label>& labels, const std::vector<Eigen::Vector2d>& positions) {
    const size_t m = labels.size();
    // A token ends where its entity's label changes away from it.
    for (size_t e = 0; e < m; ++e) {
      Running& r = running_[e];
      if (labels[e] == prev_[e] || r.step < 0) continue;
      if (keep_) step_segments_[r.step][r.segment].last_row = i - 1;
      if (r.step == step_count_ - 1 && !first_ended_) first_ended_ = Ended{r.token, i - 1};
      r.step = -1;
    }
    std::vector<Token> starting;  // tokens whose label begins in row i, by entity
    for (size_t e = 0; e < m; ++e) {
      const Label& l = labels[e];
      if (!l.isNull() && l != prev_[e]) starting.push_back({static_cast<int>(e), l.action, l.target});
    }
    if (!starting.empty()) {
      // Tokens of one step are under way together: a token joins while none has ended.
      const bool joins = step_count_ > 0 && !first_ended_;
      if (!joins) openStep(i, t, positions);
      const int k = step_count_ - 1;
      Step& step = steps_.back();
      for (const Token& token : starting) {
        step.tokens.push_back(token);
        if (joins) step.late.push_back({token, i, t - last_keyframe_t_});
        ++segment_count_;
        running_[token.entity] = {k, keep_ ? static_cast<int>(step_segments_[k].size()) : 0, token};
        if (keep_) step_segments_[k].push_back({token, k, i, i});
      }
      std::sort(step.tokens.begin(), step.tokens.end());
    }
    prev_ = labels;
    last_row_ = i;
  }

  /// Closes the running tokens at the last row and hands the steps, segments (in step
  /// order, by entity) and keyframe snapshots to `d`'s derived fields.
  void finish(std::vector<int>& keyframes, std::vector<Step>& steps, std::vector<Segment>& segments,
              std::vector<Snapshot>& snapshots) {
    for (const Running& r : running_)
      if (r.step >= 0 && keep_) step_segments_[r.step][r.segment].last_row = last_row_;
    for (auto& segs : step_segments_) {
      std::sort(segs.begin(), segs.end(), [](const Segment& a, const Segment& b) { return a.token < b.token; });
      segments.insert(segments.end(), segs.begin(), segs.end());
    }
    for (const Step& s : steps_) keyframes.push_back(s.keyframe_row);
    steps = std::move(steps_);
    snapshots = std::move(snapshots_);
  }
  const std::vector<double>& keyframeTimes() const { return keyframe_t_; }
  int stepCount() const { return step_count_; }
  size_t segmentCount() const { return segment_count_; }

 private:
  struct Running {
    int step = -1;  ///< -1: the entity runs no token
    int segment = -1;
    Token token;
  };
  struct Ended {
    Token token;
    int last_row = 0;
  };

  void openStep(int i, double t, const std::vector<Eigen::Vector2d>& positions) {
    // A token of the open step still running: this step began before that one ended.
    std::optional<StepOverlap> overlap;
    for (const Running& r : running_)
      if (first_ended_ && r.step == step_count_ - 1 && !overlap)
        overlap = StepOverlap{first_ended_->token, first_ended_->last_row, r.token};
    ++step_count_;
    last_keyframe_t_ = t;
    first_ended_.reset();
    if (!keep_) steps_.clear();
    steps_.push_back({i, {}, {}, overlap, {}});
    if (!keep_) return;
    step_segments_.emplace_back();
    snapshots_.push_back({i, false, positions});
    keyframe_t_.push_back(t);
  }

  std::vector<Label> prev_;
  std::vector<Running> running_;  ///< [entity] its running token
  std::vector<Step> steps_;
  std::vector<std::vector<Segment>> step_segments_;
  std::vector<Snapshot> snapshots_;
  std::vector<double> keyframe_t_;
  std::optional<Ended> first_ended_;  ///< the open step's first token to end
  bool keep_ = true;
  int step_count_ = 0;
  size_t segment_count_ = 0;
  double last_keyframe_t_ = 0;
  int last_row_ = -1;
};

}  // namespace

void Demonstration::analyze() {
  keyframes.clear();
  steps.clear();
  segments.clear();
  snapshots.clear();
  const size_t n = rows();
  if (n == 0) return;
  StepGrouper grouper(entities());
  for (size_t i = 0; i < n; ++i) grouper.row(static_cast<int>(i), t[i], labels[i], positions[i]);
  grouper.finish(keyframes, steps, segments, snapshots);
  snapshots.push_back({static_cast<int>(n - 1), true, positions[n - 1]});
}

std::vector<Eigen::Vector2d> Demonstration::segmentPath(const Segment& segment) const {
  std::vector<Eigen::Vector2d> path;
  for (int r = segment.first_row; r <= segment.last_row; ++r) path.push_back(positions[r][segment.token.entity]);
  return path;
}

Eigen::Vector2d Demonstration::segmentGoal(const Segment& segment) const {
  const int who = segment.token.target >= 0 ? segment.token.target : segment.token.entity;
  return positions[steps[segment.step].keyframe_row][who];
}

namespace {

/// A token of `step` that began at its keyframe (not one that joined later).
const Token& firstToken(const Step& step) {
  const auto merged = [&](const Token& t) {
    return std::any_of(step.merged.begin(), step.merged.end(), [&](const MergedStep& m) {
      return std::find(m.tokens.begin(), m.tokens.end(), t) != m.tokens.end();
    });
  };
  for (const Token& t : step.tokens)
    if (std::none_of(step.late.begin(), step.late.end(), [&](const LateOnset& l) { return l.token == t; }) &&
        !merged(t))
      return t;
  return step.tokens.front();
}

std::string tokenList(const std::vector<Token>& tokens, const TaskSpec& spec) {
  std::string s;
  for (const Token& t : tokens) s += (s.empty() ? "" : " ") + tokenKey(t, spec);
  return "[" + s + "]";
}

}  // namespace

std::vector<Diagnostic> stepGroupingNotes(const Demonstration& demo, const TaskSpec& spec) {
  return stepGroupingNotes(demo.source, demo.steps, spec);
}

std::vector<Diagnostic> stepGroupingNotes(const std::string& source, const std::vector<Step>& steps,
                                          const TaskSpec& spec) {
  std::vector<Diagnostic> notes;
  for (size_t k = 0; k < steps.size(); ++k) {
    const Step& step = steps[k];
    if (step.overlap && k > 0) {
      const std::string before = "step " + std::to_string(k);
      const std::string by = std::to_string(step.overlap->ended_row + 2);
      notes.push_back({source, step.keyframe_row + 2, 0,
                       "step " + std::to_string(k + 1) + ": " + tokenKey(firstToken(step), spec) + " began while " +
                           tokenKey(step.overlap->running, spec) + " of " + before + " still ran, after " +
                           tokenKey(step.overlap->ended, spec) + " of it had ended (line " + by +
                           "): a step of its own (a token joins a step while every token of the step runs; begin "
                           "its label by line " +
                           by + " if it belongs to " + before + ")"});
    }
    for (const MergedStep& m : step.merged)
      notes.push_back(
          {source, m.keyframe_row + 2, 0,
           "step " + std::to_string(k + 1) + ": " + tokenList(m.tokens, spec) + " began after a token of step " +
               std::to_string(k + 1) + " (line " + std::to_string(step.keyframe_row + 2) +
               ") had ended, a step of its own in this demonstration; merged into step " + std::to_string(k + 1) +
               " as " + std::to_string(m.shown_by) + " of " + std::to_string(m.demonstrations) +
               " demonstrations show such tokens in one step: check that they are one"});
    for (const LateOnset& late : step.late) {
      char delay[32];
      std::snprintf(delay, sizeof delay, "%.3f", late.delay_s);
      notes.push_back({source, late.row + 2, 0,
                       "step " + std::to_string(k + 1) + ": " + tokenKey(late.token, spec) + " began " + delay +
                           " s after the step's first token (line " + std::to_string(step.keyframe_row + 2) +
                           "); merged into the step"});
    }
  }
  return notes;
}

namespace {

/// Byte offset of the first invalid UTF-8 sequence in `s`, or npos.
size_t firstInvalidUtf8(std::string_view s) {
  size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (len == 0 || i + len > s.size()) return i;
    for (int k = 1; k < len; ++k)
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 0x2) return i;
    if (len == 2 && c < 0xC2) return i;  // overlong
    i += len;
  }
  return std::string_view::npos;
}

struct Field {
  std::string_view text;
  int column;  // 1-based byte column of the field's first character
};

/// The fields of one line, trimmed of spaces and tabs; views into `line`.
void splitLine(std::string_view line, std::vector<Field>& fields) {
  fields.clear();
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string_view f = line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start);
    size_t lead = 0;
    while (lead < f.size() && (f[lead] == ' ' || f[lead] == '\t')) ++lead;
    size_t trail = f.size();
    while (trail > lead && (f[trail - 1] == ' ' || f[trail - 1] == '\t')) --trail;
    fields.push_back({f.substr(lead, trail - lead), static_cast<int>(start + lead + 1)});
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

bool isBlank(std::string_view line) {
  return line.find_first_not_of(" \t") == std::string_view::npos;
}

enum class ColumnKind { Time, X, Y, Action, Target };

struct Column {
  ColumnKind kind;
  int entity = -1;
};

constexpr size_t kMaxErrorsPerFile = 50;

/// Parses a demonstration one line at a time, keeping only the parsed values: memory
/// grows with the rows' numbers and labels, never with the text.
class CsvParser {
 public:
  /// `keep_rows` false: the rows are analyzed as they come and dropped (summary());
  /// `keep_steps` false as well: only the last step is kept, the others counted.
  CsvParser(const TaskSpec& spec, std::string file, bool keep_rows = true, bool keep_steps = true)
      : spec_(spec),
        file_(std::move(file)),
        keep_rows_(keep_rows),
        grouper_(spec.entities.size(), keep_rows || keep_steps) {
    demo_.source = file_;
  }

  /// False once there are so many errors that reading on is pointless.
  bool wantsMore() const { return utf8_ok_ && errors_.size() < kMaxErrorsPerFile; }

  /// One physical line (without its line ending), 1-based line number.
  void line(std::string_view text, int number) {
    if (!utf8_ok_) return;  // a file that is not UTF-8 is reported as that alone
    if (number == 1 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte order mark
    const size_t bad = firstInvalidUtf8(text);
    if (bad != std::string_view::npos) {
      fail(number, static_cast<int>(bad) + 1, "file is not UTF-8 (invalid byte sequence)");
      utf8_ok_ = false;
      return;
    }
    // Blank lines at the end of a file are ignored; anywhere else they are rows.
    if (isBlank(text)) {
      ++pending_blank_;
      return;
    }
    for (; pending_blank_ > 0; --pending_blank_) process("", number - pending_blank_);
    process(text, number);
  }

  Demonstration finish() {
    checkComplete();
    demo_.analyze();
    return std::move(demo_);
  }

  DemonstrationSummary summary() {
    checkComplete();
    DemonstrationSummary s;
    s.source = file_;
    s.rows = static_cast<size_t>(rows_);
    s.t_first = t_first_;
    s.t_last = t_last_;
    s.keyframe_t = grouper_.keyframeTimes();
    std::vector<int> keyframes;
    std::vector<Segment> segments;
    std::vector<Snapshot> snapshots;
    s.step_count = static_cast<size_t>(grouper_.stepCount());
    s.segments = grouper_.segmentCount();
    grouper_.finish(keyframes, s.steps, segments, snapshots);
    s.end_row = rows_ - 1;
    return s;
  }

  void fail(int line, int column, const std::string& message) {
    if (errors_.size() < kMaxErrorsPerFile) errors_.push_back({file_, line, column, message});
  }

 private:
  void checkComplete() {
    if (!utf8_ok_) throwErrors();
    if (!header_seen_) {
      fail(1, 1, "file is empty (expected a header row t,<E>.x,<E>.y,...)");
      throwErrors();
    }
    if (errors_.empty() && rows_ == 0) fail(2, 1, "file has a header but no data rows");
    if (!errors_.empty()) throwErrors();
  }

  [[noreturn]] void throwErrors() {
    if (errors_.size() >= kMaxErrorsPerFile)
      errors_.push_back({file_, 0, 0, "too many errors; stopped after " + std::to_string(kMaxErrorsPerFile)});
    throw Error(errors_);
  }

  void process(std::string_view text, int number) {
    if (!header_seen_) {
      header_seen_ = true;
      header(text);
      return;
    }
    if (header_ok_) row(text, number);
  }

  void header(std::string_view text) {
    const size_t m = spec_.entities.size();
    splitLine(text, fields_);
    std::map<std::string, int> seen;  // column name -> 1-based column
    for (const auto& f : fields_) {
      const std::string name(f.text);
      names_.push_back(name);
      Column col{ColumnKind::Time, -1};
      bool ok = true;
      if (name == "t") {
        t_index_ = columns_.size();
      } else {
        const size_t dot = name.rfind('.');
        const std::string entity = dot == std::string::npos ? name : name.substr(0, dot);
        const std::string suffix = dot == std::string::npos ? "" : name.substr(dot + 1);
        col.entity = spec_.entityIndex(entity);
        if (suffix == "x") col.kind = ColumnKind::X;
        else if (suffix == "y") col.kind = ColumnKind::Y;
        else if (suffix == "action") col.kind = ColumnKind::Action;
        else if (suffix == "target") col.kind = ColumnKind::Target;
        else ok = false;
        if (col.entity < 0 || !ok) {
          fail(
              1, f.column,
              "unknown column '" + name + "' (expected t or <entity>.x/.y/.action/.target for an entity of task.yaml)");
          ok = false;
        }
      }
      if (ok && !seen.emplace(name, f.column).second) {
        fail(1, f.column, "duplicated column '" + name + "'");
        ok = false;
      }
      header_ok_ = header_ok_ && ok;
      columns_.push_back(col);
    }
    auto missing = [&](const std::string& name) {
      if (!seen.count(name)) {
        fail(1, 1, "missing required column '" + name + "'");
        header_ok_ = false;
      }
    };
    missing("t");
    demo_.has_label_columns.assign(m, false);
    for (size_t e = 0; e < m; ++e) {
      const std::string& n = spec_.entities[e].name;
      missing(n + ".x");
      missing(n + ".y");
      const bool has_action = seen.count(n + ".action") > 0;
      if (seen.count(n + ".target") && !has_action) {
        fail(1, seen[n + ".target"], "column '" + n + ".target' without '" + n + ".action'");
        header_ok_ = false;
      }
      demo_.has_label_columns[e] = has_action;
    }
  }

  void row(std::string_view text, int line) {
    const size_t m = spec_.entities.size();
    splitLine(text, fields_);
    if (fields_.size() != columns_.size()) {
      const int col =
          fields_.size() > columns_.size() ? fields_[columns_.size()].column : static_cast<int>(text.size()) + 1;
      fail(line, col,
           "row has " + std::to_string(fields_.size()) + " fields, the header has " + std::to_string(columns_.size()) +
               (fields_.size() > columns_.size() ? " (too many)" : " (too few)"));
      return;
    }
    double t = 0;
    std::vector<Eigen::Vector2d> pos(m, Eigen::Vector2d::Zero());
    std::vector<Label> labels(m);
    std::vector<int> target_column(m, 0);
    bool row_ok = true;
    for (size_t c = 0; c < columns_.size(); ++c) {
      const Field& f = fields_[c];
      const Column& col = columns_[c];
      const std::string& cname = names_[c];
      switch (col.kind) {
        case ColumnKind::Time:
        case ColumnKind::X:
        case ColumnKind::Y: {
          double v = 0;
          if (!detail::parseFiniteNumber(f.text, v)) {
            fail(line, f.column, cname + ": '" + printable(f.text) + "' is not a finite number");
            row_ok = false;
          } else if (col.kind == ColumnKind::Time) {
            t = v;
          } else {
            pos[col.entity][col.kind == ColumnKind::X ? 0 : 1] = v;
          }
          break;
        }
        case ColumnKind::Action: {
          if (f.text.empty() || f.text == "idle") break;
          const std::string a(f.text);
          if (!isValidName(a)) {
            fail(line, f.column, cname + ": '" + printable(f.text) + "' is not an action word");
            row_ok = false;
          } else if (!spec_.allowsAction(a)) {
            fail(line, f.column, cname + ": action '" + a + "' is not in task.yaml's actions");
            row_ok = false;
          } else {
            labels[col.entity].action = a;
          }
          break;
        }
        case ColumnKind::Target: {
          if (f.text.empty()) break;
          const std::string target(f.text);
          target_column[col.entity] = f.column;
          labels[col.entity].target = spec_.entityIndex(target);
          if (labels[col.entity].target < 0) {
            fail(line, f.column, cname + ": unknown target '" + printable(f.text) + "'");
            row_ok = false;
          } else if (labels[col.entity].target == col.entity) {
            fail(line, f.column, cname + ": an entity cannot target itself");
            row_ok = false;
          }
          break;
        }
      }
    }
    for (size_t e = 0; e < m; ++e) {
      if (labels[e].target >= 0 && labels[e].action.empty() && row_ok) {
        fail(line, target_column[e],
             spec_.entities[e].name + ".target: target '" + spec_.entities[labels[e].target].name +
                 "' without an action");
        row_ok = false;
      }
    }
    if (!row_ok) return;
    if (rows_ > 0 && !(t > t_last_)) {
      fail(line, fields_[t_index_].column,
           "t = " + std::string(fields_[t_index_].text) +
               " is not strictly increasing (previous row: " + detail::shortestNumber(t_last_) + ")");
    }
    if (rows_ == 0) t_first_ = t;
    t_last_ = t;
    if (keep_rows_) {
      demo_.t.push_back(t);
      demo_.positions.push_back(std::move(pos));
      demo_.labels.push_back(std::move(labels));
    } else if (errors_.empty()) {  // only an error-free file is analyzed
      grouper_.row(rows_, t, labels, pos);
    }
    ++rows_;
  }

  /// The field as it can be shown in a message (control bytes, NUL included, escaped).
  static std::string printable(std::string_view s) {
    std::string out;
    for (char c : s) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned char>(c));
        out += buf;
      } else {
        out += c;
      }
    }
    return out;
  }

  const TaskSpec& spec_;
  std::string file_;
  bool keep_rows_;
  StepGrouper grouper_;
  int rows_ = 0;
  double t_first_ = 0, t_last_ = 0;
  Demonstration demo_;
  std::vector<Diagnostic> errors_;
  std::vector<Column> columns_;
  std::vector<std::string> names_;
  std::vector<Field> fields_;
  size_t t_index_ = 0;
  bool header_seen_ = false, header_ok_ = true, utf8_ok_ = true;
  int pending_blank_ = 0;
};

/// Splits bytes into lines ending in LF, CRLF or CR alone and hands them to `parser`;
/// a CR at the end of one chunk and an LF at the start of the next are one ending.
class LineSplitter {
 public:
  explicit LineSplitter(CsvParser& parser) : parser_(parser) {}

  void feed(std::string_view bytes) {
    size_t start = 0;
    for (size_t i = 0; i < bytes.size(); ++i) {
      const char c = bytes[i];
      if (c != '\n' && c != '\r') continue;
      if (c == '\n' && after_cr_ && i == start && current_.empty()) {  // the LF of a CRLF
        after_cr_ = false;
        start = i + 1;
        continue;
      }
      current_.append(bytes.data() + start, i - start);
      emit();
      after_cr_ = c == '\r';
      start = i + 1;
    }
    if (start < bytes.size()) {
      current_.append(bytes.data() + start, bytes.size() - start);
      after_cr_ = false;
      if (current_.size() > kMaxLineBytes) {
        parser_.fail(number_ + 1, 1, "line longer than " + std::to_string(kMaxLineBytes) + " bytes");
        overlong_ = true;
        current_.clear();
      }
    }
  }

  /// Ends the input (a last line without a line ending).
  void finish() {
    if (!current_.empty() || overlong_) emit();
  }
  bool wantsMore() const { return parser_.wantsMore() && !overlong_; }

 private:
  static constexpr size_t kMaxLineBytes = 1 << 20;

  void emit() {
    ++number_;
    if (!overlong_) parser_.line(current_, number_);
    current_.clear();
  }

  CsvParser& parser_;
  std::string current_;
  int number_ = 0;
  bool after_cr_ = false, overlong_ = false;
};

}  // namespace

Demonstration parseDemonstrationCsv(const std::string& text, const TaskSpec& spec, const std::string& file) {
  CsvParser parser(spec, file);
  LineSplitter lines(parser);
  lines.feed(text);
  lines.finish();
  return parser.finish();
}

namespace {

/// Streams the CSV at `path` through `parser`, refusing more than `max_bytes`.
void readCsv(const std::string& path, CsvParser& parser, std::uint64_t max_bytes) {
  InputFile in(path, max_bytes);
  LineSplitter lines(parser);
  char chunk[65536];
  std::streambuf* buf = in.stream().rdbuf();
  while (lines.wantsMore()) {
    const std::streamsize n = buf->sgetn(chunk, sizeof chunk);
    if (n <= 0) break;
    lines.feed(std::string_view(chunk, static_cast<size_t>(n)));
  }
  if (in.exceeded())
    throw Error(Diagnostic{
        path, 0, 0, "cannot read: more than the limit of " + std::to_string(max_bytes) + " bytes for a demonstration"});
  lines.finish();
}

}  // namespace

Demonstration readDemonstrationCsv(const std::string& path, const TaskSpec& spec) {
  CsvParser parser(spec, path);
  readCsv(path, parser, kMaxDemonstrationBytes);
  return parser.finish();
}

DemonstrationSummary summarizeDemonstrationCsv(const std::string& path, const TaskSpec& spec, bool keep_steps) {
  CsvParser parser(spec, path, false, keep_steps);
  // No byte limit: no row is kept, a file of any length streams through.
  readCsv(path, parser, std::numeric_limits<std::uint64_t>::max());
  return parser.summary();
}

namespace {

void writeCsv(std::ostream& out, const Demonstration& demo, const TaskSpec& spec) {
  const size_t m = spec.entities.size();
  std::string line = "t";
  for (size_t e = 0; e < m; ++e) {
    const std::string& n = spec.entities[e].name;
    line += "," + n + ".x," + n + ".y";
    if (demo.has_label_columns[e]) line += "," + n + ".action," + n + ".target";
  }
  out << line << '\n';
  for (size_t r = 0; r < demo.rows(); ++r) {
    line = detail::csvNumber(demo.t[r]);
    for (size_t e = 0; e < m; ++e) {
      const auto& p = demo.positions[r][e];
      line += ',';
      line += detail::csvNumber(p.x());
      line += ',';
      line += detail::csvNumber(p.y());
      if (demo.has_label_columns[e]) {
        const Label& l = demo.labels[r][e];
        line += ',';
        line += l.action;
        line += ',';
        if (l.target >= 0) line += spec.entities[l.target].name;
      }
    }
    out << line << '\n';
  }
}

}  // namespace

std::string demonstrationCsvText(const Demonstration& demo, const TaskSpec& spec) {
  std::ostringstream out;
  writeCsv(out, demo, spec);
  return out.str();
}

void writeDemonstrationCsv(const Demonstration& demo, const TaskSpec& spec, const std::string& path) {
  OutputFile out(path);
  writeCsv(out.stream(), demo, spec);
  out.commit();
}

}  // namespace ddace::task
