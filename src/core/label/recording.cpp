#include "ddace/label/recording.h"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string_view>
#include <algorithm>
#include <cerrno>
#include <cmath>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/task/demonstration.h"

namespace ddace::label {

using Eigen::Vector2d;

namespace {

/// Streams the lines of `path` (LF, CRLF or CR endings, a UTF-8 byte-order mark dropped,
/// blank lines skipped) to `line(number, text)`.
void forEachLine(const std::string& path, const std::function<void(int, std::string_view)>& line) {
  // No byte limit: nothing of the file is held, a recording of any length streams.
  InputFile in(path, std::numeric_limits<std::uint64_t>::max());
  std::streambuf* buf = in.stream().rdbuf();
  std::string current;
  int number = 0;
  bool after_cr = false;
  auto emit = [&]() {
    ++number;
    std::string_view text(current);
    if (number == 1 && text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    if (text.find_first_not_of(" \t") != std::string_view::npos) line(number, text);
    current.clear();
  };
  char chunk[65536];
  for (;;) {
    const std::streamsize n = buf->sgetn(chunk, sizeof chunk);
    if (n <= 0) break;
    for (std::streamsize i = 0; i < n; ++i) {
      const char c = chunk[i];
      if (c == '\n' && after_cr) {
        after_cr = false;
        continue;
      }
      after_cr = c == '\r';
      if (c == '\n' || c == '\r') emit();
      else current += c;
    }
  }
  if (!current.empty()) emit();
}

void split(std::string_view text, std::vector<std::string_view>& fields) {
  fields.clear();
  size_t start = 0;
  for (;;) {
    const size_t comma = text.find(',', start);
    fields.push_back(text.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

/// The columns of a header: t, and [entity] x and y.
struct Columns {
  size_t count = 0, t = 0;
  std::vector<size_t> x, y;
};

Columns header(const std::string& path, std::string_view text, const task::TaskSpec& spec) {
  std::vector<std::string_view> fields;
  split(text, fields);
  Columns c;
  c.count = fields.size();
  const size_t m = spec.entities.size();
  c.x.assign(m, fields.size());
  c.y.assign(m, fields.size());
  for (size_t i = 0; i < fields.size(); ++i) {
    const std::string f(fields[i]);
    if (f == "t") c.t = i;
    for (size_t e = 0; e < m; ++e) {
      if (f == spec.entities[e].name + ".x") c.x[e] = i;
      if (f == spec.entities[e].name + ".y") c.y[e] = i;
    }
  }
  for (size_t e = 0; e < m; ++e)
    if (c.x[e] == fields.size() || c.y[e] == fields.size())
      throw Error(Diagnostic{path, 1, 1, "no position columns for " + spec.entities[e].name + " (the file changed?)"});
  return c;
}

/// The 1-based byte column of `field`, a view into `text`.
int columnOf(std::string_view text, std::string_view field) {
  return static_cast<int>(field.data() - text.data()) + 1;
}

double number(const std::string& path, int line, std::string_view text, std::string_view field) {
  const std::string s(field);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v))
    throw Error(Diagnostic{path, line, columnOf(text, field),
                           "'" + s + "' is not a finite number (the file changed since it was checked?)"});
  return v;
}

/// Streams rows: the header's columns, then per row its fields and parsed values.
void forEachParsedRow(const std::string& path, const task::TaskSpec& spec,
                      const std::function<void(const Columns&, int, const std::vector<std::string_view>&, double,
                                               const std::vector<Vector2d>&)>& row) {
  Columns cols;
  bool have_header = false;
  std::vector<std::string_view> fields;
  std::vector<Vector2d> p(spec.entities.size());
  forEachLine(path, [&](int line, std::string_view text) {
    if (!have_header) {
      cols = header(path, text, spec);
      have_header = true;
      return;
    }
    split(text, fields);
    if (fields.size() != cols.count)
      throw Error(Diagnostic{
          path, line,
          fields.size() > cols.count ? columnOf(text, fields[cols.count]) : static_cast<int>(text.size()) + 1,
          "row has " + std::to_string(fields.size()) + " fields, the header " + std::to_string(cols.count) +
              " (the file changed since it was checked?)"});
    const double t = number(path, line, text, fields[cols.t]);
    for (size_t e = 0; e < p.size(); ++e)
      p[e] = {number(path, line, text, fields[cols.x[e]]), number(path, line, text, fields[cols.y[e]])};
    row(cols, line, fields, t, p);
  });
}

}  // namespace

void forEachRow(const std::string& path, const task::TaskSpec& spec,
                const std::function<void(int, double, const std::vector<Vector2d>&)>& row) {
  forEachParsedRow(path, spec,
                   [&](const Columns&, int line, const std::vector<std::string_view>&, double t,
                       const std::vector<Vector2d>& p) { row(line, t, p); });
}

RecordingInference inferRecording(const std::string& path, const task::TaskSpec& spec, const Example* example,
                                  const std::function<void(InferredStep&&)>& on_step,
                                  const std::function<void(Note&&)>& on_note) {
  RecordingInference r;
  r.labelled.assign(spec.entities.size(), false);
  auto hand = [&](Inference inf) {
    for (auto& s : inf.steps) {
      ++r.steps;
      r.tokens += s.tokens.size();
      for (const auto& t : s.tokens) r.labelled[t.token.entity] = true;
      on_step(std::move(s));
    }
    r.notes += inf.notes.size();
    for (auto& n : inf.notes) on_note(std::move(n));
  };
  Labeller labeller(spec, example);
  forEachRow(path, spec, [&](int, double t, const std::vector<Vector2d>& p) {
    labeller.row(t, p);
    hand(labeller.take());
  });
  r.rows = static_cast<size_t>(labeller.rows());
  hand(labeller.finish());
  return r;
}

Inference inferRecording(const std::string& path, const task::TaskSpec& spec, const Example* example) {
  Labeller labeller(spec, example);
  forEachRow(path, spec, [&](int, double t, const std::vector<Vector2d>& p) { labeller.row(t, p); });
  return labeller.finish();
}

namespace {

/// One token on disk: its span and an index into the spill's action words.
struct SpillRecord {
  std::int32_t first, last, entity, target, action;
};

}  // namespace

TokenSpill::TokenSpill() : file_(std::tmpfile()) {
  if (!file_) throw Error(std::string("cannot make a temporary file for the inferred tokens: ") + std::strerror(errno));
}

TokenSpill::~TokenSpill() {
  std::fclose(file_);
}

void TokenSpill::add(const InferredStep& step) {
  for (const auto& t : step.tokens) {
    auto it = std::find(actions_.begin(), actions_.end(), t.token.action);
    if (it == actions_.end()) it = actions_.insert(actions_.end(), t.token.action);
    const SpillRecord r{t.first_row, t.last_row, t.token.entity, t.token.target,
                        static_cast<std::int32_t>(it - actions_.begin())};
    if (std::fseek(file_, 0, SEEK_END) != 0 || std::fwrite(&r, sizeof r, 1, file_) != 1)
      throw Error(std::string("cannot write the inferred tokens to a temporary file: ") + std::strerror(errno));
    ++written_;
  }
}

std::function<bool(LabelCursor::Span&)> TokenSpill::reader(size_t from, size_t to) {
  if (std::fflush(file_) != 0) throw Error(std::string("cannot write the temporary file: ") + std::strerror(errno));
  return [this, at = from, to](LabelCursor::Span& s) mutable {
    if (at >= to) return false;
    SpillRecord r;
    if (std::fseek(file_, static_cast<long>(at * sizeof r), SEEK_SET) != 0 || std::fread(&r, sizeof r, 1, file_) != 1)
      throw Error(std::string("cannot read the inferred tokens back from a temporary file: ") + std::strerror(errno));
    ++at;
    s = {r.first, r.last, r.entity, {actions_.at(static_cast<size_t>(r.action)), r.target}};
    return true;
  };
}

void writeLabelledRecording(const std::string& path, const task::TaskSpec& spec, const Inference& inference,
                            std::ostream& out) {
  std::vector<bool> labelled(spec.entities.size(), false);
  for (const auto& s : inference.steps)
    for (const auto& t : s.tokens) labelled[t.token.entity] = true;
  LabelCursor cursor(inference, spec.entities.size());
  writeLabelledRecording(path, spec, labelled, cursor, out);
}

void writeLabelledRecording(const std::string& path, const task::TaskSpec& spec, const std::vector<bool>& labelled,
                            LabelCursor& cursor, std::ostream& out) {
  const size_t m = spec.entities.size();
  std::string line = "t";
  for (size_t e = 0; e < m; ++e) {
    const std::string& n = spec.entities[e].name;
    line += "," + n + ".x," + n + ".y";
    if (labelled[e]) line += "," + n + ".action," + n + ".target";
  }
  out << line << '\n';
  int row = 0;
  forEachParsedRow(
      path, spec,
      [&](const Columns& c, int, const std::vector<std::string_view>& f, double, const std::vector<Vector2d>&) {
        const auto& labels = cursor.at(row++);
        line.assign(f[c.t]);
        for (size_t e = 0; e < m; ++e) {
          line += ',';
          line += f[c.x[e]];
          line += ',';
          line += f[c.y[e]];
          if (!labelled[e]) continue;
          line += ',';
          line += labels[e].action;
          line += ',';
          if (labels[e].target >= 0) line += spec.entities[labels[e].target].name;
        }
        out << line << '\n';
      });
  if (!cursor.exhausted())
    throw Error(Diagnostic{path, 0, 0, "inferred tokens beyond its last row (the file changed since it was read?)"});
}

}  // namespace ddace::label
