#include "ddace/common/file.h"
#include "ddace/task/demonstration.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

namespace ddace::task {

bool Token::operator<(const Token& o) const {
  if (entity != o.entity) return entity < o.entity;
  if (action != o.action) return action < o.action;
  return target < o.target;
}

std::string tokenKey(const Token& token, const TaskSpec& spec) {
  auto name = [&](int i) {
    return i >= 0 && i < static_cast<int>(spec.entities.size()) ? spec.entities[i].name
                                                                : "#" + std::to_string(i);
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

void Demonstration::analyze() {
  keyframes.clear();
  steps.clear();
  segments.clear();
  snapshots.clear();
  const size_t n = rows(), m = entities();
  if (n == 0) return;
  const std::vector<Label> none(m);
  std::vector<std::vector<Segment>> step_segments;
  int open_until = -1;  // the current step's tokens all hold up to this row (none has ended)
  auto openStep = [&](size_t row) {
    steps.push_back({static_cast<int>(row), {}, {}});
    step_segments.emplace_back();
    keyframes.push_back(static_cast<int>(row));
    snapshots.push_back({static_cast<int>(row), false, positions[row]});
    open_until = static_cast<int>(n);
  };
  for (size_t i = 0; i < n; ++i) {
    const auto& prev = i == 0 ? none : labels[i - 1];
    std::vector<Segment> starting;  // tokens whose label begins in row i, by entity
    for (size_t e = 0; e < m; ++e) {
      const Label& l = labels[i][e];
      if (l.isNull() || l == prev[e]) continue;
      size_t last = i;
      while (last + 1 < n && labels[last + 1][e] == l) ++last;
      starting.push_back({{static_cast<int>(e), l.action, l.target}, 0, static_cast<int>(i), static_cast<int>(last)});
    }
    if (starting.empty()) {
      // The bare rule (window 0) also makes a keyframe, with no token, of a row in which
      // labels only end while others hold; with grouping only a beginning label opens a step.
      bool all_null = true;
      for (const auto& l : labels[i]) all_null = all_null && l.isNull();
      if (step_window_s == 0 && !all_null && labels[i] != prev) openStep(i);
      continue;
    }
    const bool joins = !steps.empty() && static_cast<int>(i) <= open_until &&
                       t[i] - t[steps.back().keyframe_row] <= step_window_s;
    if (!joins) openStep(i);
    Step& step = steps.back();
    for (auto& seg : starting) {
      seg.step = static_cast<int>(steps.size()) - 1;
      step.tokens.push_back(seg.token);
      if (joins) step.late.push_back({seg.token, static_cast<int>(i), t[i] - t[step.keyframe_row]});
      open_until = std::min(open_until, seg.last_row);
      step_segments.back().push_back(std::move(seg));
    }
    std::sort(step.tokens.begin(), step.tokens.end());
  }
  for (auto& segs : step_segments) {
    std::sort(segs.begin(), segs.end(), [](const Segment& a, const Segment& b) { return a.token < b.token; });
    segments.insert(segments.end(), segs.begin(), segs.end());
  }
  snapshots.push_back({static_cast<int>(n - 1), true, positions[n - 1]});
}

std::vector<Eigen::Vector2d> Demonstration::segmentPath(const Segment& segment) const {
  std::vector<Eigen::Vector2d> path;
  for (int r = segment.first_row; r <= segment.last_row; ++r)
    path.push_back(positions[r][segment.token.entity]);
  return path;
}

Eigen::Vector2d Demonstration::segmentGoal(const Segment& segment) const {
  const int who = segment.token.target >= 0 ? segment.token.target : segment.token.entity;
  return positions[steps[segment.step].keyframe_row][who];
}

std::vector<Diagnostic> mergedOnsetNotes(const Demonstration& demo, const TaskSpec& spec) {
  std::vector<Diagnostic> notes;
  for (size_t k = 0; k < demo.steps.size(); ++k) {
    const Step& step = demo.steps[k];
    for (const LateOnset& late : step.late) {
      char delay[32];
      std::snprintf(delay, sizeof delay, "%.3f", late.delay_s);
      notes.push_back({demo.source, late.row + 2, 0,
                       "step " + std::to_string(k + 1) + ": " + tokenKey(late.token, spec) + " began " + delay +
                           " s after the step's first token (line " + std::to_string(step.keyframe_row + 2) +
                           "); merged into the step"});
    }
  }
  return notes;
}

namespace {

/// Byte offset of the first invalid UTF-8 sequence, or npos.
size_t firstInvalidUtf8(const std::string& s) {
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
  return std::string::npos;
}

struct Field {
  std::string text;
  int column;  // 1-based character column of the field's first character
};

std::vector<Field> splitLine(const std::string& line) {
  std::vector<Field> fields;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string f = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    size_t lead = 0;
    while (lead < f.size() && (f[lead] == ' ' || f[lead] == '\t')) ++lead;
    size_t trail = f.size();
    while (trail > lead && (f[trail - 1] == ' ' || f[trail - 1] == '\t')) --trail;
    fields.push_back({f.substr(lead, trail - lead), static_cast<int>(start + lead + 1)});
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

bool parseNumber(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  out = std::strtod(s.c_str(), &end);
  return *end == '\0' && std::isfinite(out);
}

enum class ColumnKind { Time, X, Y, Action, Target };

struct Column {
  ColumnKind kind;
  int entity = -1;
};

constexpr size_t kMaxErrorsPerFile = 50;

}  // namespace

Demonstration parseDemonstrationCsv(const std::string& input, const TaskSpec& spec,
                                    const std::string& file) {
  std::vector<Diagnostic> errors;
  auto fail = [&](int line, int column, const std::string& message) {
    if (errors.size() < kMaxErrorsPerFile) errors.push_back({file, line, column, message});
  };
  auto finish = [&]() {
    if (errors.size() >= kMaxErrorsPerFile)
      errors.push_back({file, 0, 0, "too many errors; stopped after " + std::to_string(kMaxErrorsPerFile)});
    throw Error(errors);
  };

  std::string text = input;
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);  // UTF-8 byte order mark
  const size_t bad = firstInvalidUtf8(text);
  if (bad != std::string::npos) {
    const size_t line_start = text.rfind('\n', bad == 0 ? 0 : bad - 1);
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + bad, '\n'));
    const int column = static_cast<int>(bad - (line_start == std::string::npos || bad == 0 ? 0 : line_start + 1)) + 1;
    fail(line, column, "file is not UTF-8 (invalid byte sequence)");
    finish();
  }

  std::vector<std::string> lines;
  {
    std::string line;
    std::istringstream in(text);
    while (std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      lines.push_back(line);
    }
    while (!lines.empty() && lines.back().find_first_not_of(" \t") == std::string::npos) lines.pop_back();
  }
  if (lines.empty()) {
    fail(1, 1, "file is empty (expected a header row t,<E>.x,<E>.y,...)");
    finish();
  }

  // Header.
  const size_t m = spec.entities.size();
  const std::vector<Field> header = splitLine(lines[0]);
  std::vector<Column> columns;
  std::map<std::string, int> seen;  // column name -> 1-based character column
  size_t t_index = 0;
  bool header_ok = true;
  for (const auto& f : header) {
    Column col{ColumnKind::Time, -1};
    bool ok = true;
    if (f.text == "t") {
      col.kind = ColumnKind::Time;
      t_index = columns.size();
    } else {
      const size_t dot = f.text.rfind('.');
      const std::string name = dot == std::string::npos ? f.text : f.text.substr(0, dot);
      const std::string suffix = dot == std::string::npos ? "" : f.text.substr(dot + 1);
      col.entity = spec.entityIndex(name);
      if (suffix == "x") col.kind = ColumnKind::X;
      else if (suffix == "y") col.kind = ColumnKind::Y;
      else if (suffix == "action") col.kind = ColumnKind::Action;
      else if (suffix == "target") col.kind = ColumnKind::Target;
      else ok = false;
      if (col.entity < 0 || !ok) {
        fail(1, f.column, "unknown column '" + f.text + "' (expected t or <entity>.x/.y/.action/.target for an entity of task.yaml)");
        ok = false;
      }
    }
    if (ok && !seen.emplace(f.text, f.column).second) {
      fail(1, f.column, "duplicated column '" + f.text + "'");
      ok = false;
    }
    header_ok = header_ok && ok;
    columns.push_back(col);
  }
  auto missing = [&](const std::string& name) {
    if (!seen.count(name)) {
      fail(1, 1, "missing required column '" + name + "'");
      header_ok = false;
    }
  };
  missing("t");
  Demonstration demo;
  demo.source = file;
  demo.step_window_s = spec.step_window_s;
  demo.has_label_columns.assign(m, false);
  for (size_t e = 0; e < m; ++e) {
    const std::string& n = spec.entities[e].name;
    missing(n + ".x");
    missing(n + ".y");
    const bool has_action = seen.count(n + ".action") > 0;
    if (seen.count(n + ".target") && !has_action) {
      fail(1, seen[n + ".target"], "column '" + n + ".target' without '" + n + ".action'");
      header_ok = false;
    }
    demo.has_label_columns[e] = has_action;
  }
  if (!header_ok) finish();

  // Rows.
  for (size_t li = 1; li < lines.size(); ++li) {
    const int line = static_cast<int>(li) + 1;
    const std::vector<Field> fields = splitLine(lines[li]);
    if (fields.size() != columns.size()) {
      const int col = fields.size() > columns.size() ? fields[columns.size()].column
                                                     : static_cast<int>(lines[li].size()) + 1;
      fail(line, col, "row has " + std::to_string(fields.size()) + " fields, the header has " +
                          std::to_string(columns.size()) +
                          (fields.size() > columns.size() ? " (too many)" : " (too few)"));
      continue;
    }
    double t = 0;
    std::vector<Eigen::Vector2d> pos(m, Eigen::Vector2d::Zero());
    std::vector<Label> labels(m);
    std::vector<int> target_column(m, 0);
    bool row_ok = true;
    for (size_t c = 0; c < columns.size(); ++c) {
      const Field& f = fields[c];
      const Column& col = columns[c];
      const std::string& cname = header[c].text;
      switch (col.kind) {
        case ColumnKind::Time:
        case ColumnKind::X:
        case ColumnKind::Y: {
          double v = 0;
          if (!parseNumber(f.text, v)) {
            fail(line, f.column, cname + ": '" + f.text + "' is not a finite number");
            row_ok = false;
          } else if (col.kind == ColumnKind::Time) {
            t = v;
          } else {
            pos[col.entity][col.kind == ColumnKind::X ? 0 : 1] = v;
          }
          break;
        }
        case ColumnKind::Action:
          if (f.text.empty() || f.text == "idle") break;
          if (!isValidName(f.text)) {
            fail(line, f.column, cname + ": '" + f.text + "' is not an action word");
            row_ok = false;
          } else if (!spec.allowsAction(f.text)) {
            fail(line, f.column, cname + ": action '" + f.text + "' is not in task.yaml's actions");
            row_ok = false;
          } else {
            labels[col.entity].action = f.text;
          }
          break;
        case ColumnKind::Target:
          if (f.text.empty()) break;
          target_column[col.entity] = f.column;
          labels[col.entity].target = spec.entityIndex(f.text);
          if (labels[col.entity].target < 0) {
            fail(line, f.column, cname + ": unknown target '" + f.text + "'");
            row_ok = false;
          } else if (labels[col.entity].target == col.entity) {
            fail(line, f.column, cname + ": an entity cannot target itself");
            row_ok = false;
          }
          break;
      }
    }
    for (size_t e = 0; e < m; ++e) {
      if (labels[e].target >= 0 && labels[e].action.empty() && row_ok) {
        fail(line, target_column[e], spec.entities[e].name + ".target: target '" +
                                         spec.entities[labels[e].target].name + "' without an action");
        row_ok = false;
      }
    }
    if (!row_ok) continue;
    if (!demo.t.empty() && !(t > demo.t.back())) {
      fail(line, fields[t_index].column, "t = " + fields[t_index].text + " is not strictly increasing (previous row: " + std::to_string(demo.t.back()) + ")");
    }
    demo.t.push_back(t);
    demo.positions.push_back(std::move(pos));
    demo.labels.push_back(std::move(labels));
  }
  if (errors.empty() && demo.t.empty()) fail(2, 1, "file has a header but no data rows");
  if (!errors.empty()) finish();
  demo.analyze();
  return demo;
}

Demonstration readDemonstrationCsv(const std::string& path, const TaskSpec& spec) {
  return parseDemonstrationCsv(readTextFile(path), spec, path);
}

std::string demonstrationCsvText(const Demonstration& demo, const TaskSpec& spec) {
  std::string out = "t";
  const size_t m = spec.entities.size();
  for (size_t e = 0; e < m; ++e) {
    const std::string& n = spec.entities[e].name;
    out += "," + n + ".x," + n + ".y";
    if (demo.has_label_columns[e]) out += "," + n + ".action," + n + ".target";
  }
  out += "\n";
  char buf[64];
  for (size_t r = 0; r < demo.rows(); ++r) {
    std::snprintf(buf, sizeof buf, "%.6f", demo.t[r]);
    out += buf;
    for (size_t e = 0; e < m; ++e) {
      const auto& p = demo.positions[r][e];
      std::snprintf(buf, sizeof buf, ",%.6f,%.6f", p.x(), p.y());
      out += buf;
      if (demo.has_label_columns[e]) {
        const Label& l = demo.labels[r][e];
        out += "," + l.action + "," + (l.target >= 0 ? spec.entities[l.target].name : "");
      }
    }
    out += "\n";
  }
  return out;
}

void writeDemonstrationCsv(const Demonstration& demo, const TaskSpec& spec, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(Diagnostic{path, 0, 0, "cannot write file"});
  out << demonstrationCsvText(demo, spec);
  if (!out) throw Error(Diagnostic{path, 0, 0, "write failed"});
}

}  // namespace ddace::task
