#include "ddace/label/human_motion.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace ddace::label {

using Eigen::Vector2d;

namespace {

/// `v` in whole micrometres, as a file holds it (so a demonstration reads back exactly).
double micrometres(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6f", v);
  return std::strtod(buf, nullptr);
}

/// One motion of a step as the person makes it.
struct Moved {
  int entity;
  std::vector<Vector2d> path;               ///< the generated positions, evenly in time
  double delay, duration, pause_at, pause;  ///< seconds from the step's start; pause_at in [0, 1] of duration
  double end() const { return delay + duration + pause; }
  Vector2d at(double tau) const {
    double q = tau - delay;
    if (q <= 0) return path.front();
    if (pause > 0 && q > pause_at * duration) q = std::max(pause_at * duration, q - pause);
    const double u = std::min(q / duration, 1.0) * static_cast<double>(path.size() - 1);
    const size_t i = std::min(static_cast<size_t>(u), path.size() - 1);
    if (i + 1 >= path.size()) return path.back();
    return path[i] + (u - static_cast<double>(i)) * (path[i + 1] - path[i]);
  }
};

}  // namespace

task::Demonstration humanMotion(const task::Demonstration& clean, const task::TaskSpec& spec,
                                const HumanMotionOptions& o, SplitMix64& rng) {
  const size_t m = spec.entities.size();
  task::Demonstration d;
  d.source = clean.source;
  d.step_window_s = clean.step_window_s;
  d.has_label_columns = clean.has_label_columns;
  std::vector<Vector2d> pos = clean.positions.front();
  const double dt = 1.0 / o.rate_hz;
  auto emit = [&](const std::vector<task::Label>& labels) {
    d.t.push_back(static_cast<double>(d.t.size()) / o.rate_hz);
    d.positions.push_back(pos);
    d.labels.push_back(labels);
  };
  const std::vector<task::Label> idle(m);
  auto rest = [&](double seconds) {
    for (int i = 0, n = static_cast<int>(std::round(seconds / dt)); i < n; ++i) emit(idle);
  };
  // Between two steps: a person's pause, perhaps bumping a robot and putting it back.
  auto gap = [&]() {
    const double g = rng.uniform(o.gap_min_s, o.gap_max_s);
    std::vector<int> robots;
    for (size_t e = 0; e < m; ++e)
      if (spec.entities[e].kind == task::EntityKind::Robot) robots.push_back(static_cast<int>(e));
    if (robots.empty() || rng.uniform() >= o.nudge_probability) return rest(g);
    const int r = robots[rng.index(robots.size())];
    const Vector2d home = pos[r];
    const double a = rng.uniform(0, 2 * M_PI), dist = rng.uniform(o.nudge_min_m, o.nudge_max_m);
    const Vector2d away = home + dist * Vector2d(std::cos(a), std::sin(a));
    rest(0.3);
    const int n = static_cast<int>(std::round(0.25 / dt));
    for (int i = 1; i <= n; ++i) pos[r] = home + (away - home) * i / n, emit(idle);
    rest(0.3);
    for (int i = 1; i <= n; ++i) pos[r] = away + (home - away) * i / n, emit(idle);
    rest(std::max(o.gap_min_s, g - 1.1));  // the hand goes on to the next robot
  };

  rest(rng.uniform(0.5, 1.0));
  for (size_t k = 0; k < clean.steps.size(); ++k) {
    std::vector<const task::Segment*> segs;
    for (const auto& s : clean.segments)
      if (s.step == static_cast<int>(k)) segs.push_back(&s);
    std::vector<Moved> moved;
    std::vector<int> leader;                // [moved] index of the motion it follows (a load), or -1
    std::vector<task::Token> moved_tokens;  // [moved]
    for (const auto* s : segs) {
      if (!s->token.isMotion()) continue;
      auto path = clean.segmentPath(*s);
      if ((path.back() - path.front()).norm() < 1e-3) continue;
      Moved mv{s->token.entity, path, 0, 0, 0, 0};
      // A load moves with its carrier (task::carriedLoad: a robot of the step with the same
      // action and target; its path runs in front of the carrier's, docs/task-format.md).
      int follows = -1;
      if (spec.entities[mv.entity].kind == task::EntityKind::Object)
        for (size_t j = 0; j < moved.size(); ++j)
          if (spec.entities[moved[j].entity].kind == task::EntityKind::Robot &&
              moved_tokens[j].action == s->token.action && moved_tokens[j].target == s->token.target)
            follows = static_cast<int>(j);
      const double generated = clean.t[s->last_row] - clean.t[s->first_row];
      if (follows >= 0) {
        const Moved& l = moved[follows];
        mv.delay = l.delay, mv.duration = l.duration, mv.pause_at = l.pause_at, mv.pause = l.pause;
      } else {
        mv.delay = rng.uniform(0, o.onset_spread_s);
        mv.duration = generated / rng.uniform(o.speed_min, o.speed_max);
        if (rng.uniform() < o.pause_probability)
          mv.pause_at = rng.uniform(0.3, 0.7), mv.pause = rng.uniform(o.pause_min_s, o.pause_max_s);
      }
      moved.push_back(mv);
      moved_tokens.push_back(s->token);
      leader.push_back(follows);
    }
    // The first motion starts the step.
    double first = 1e9;
    for (const auto& mv : moved) first = std::min(first, mv.delay);
    for (auto& mv : moved) mv.delay -= first;
    double end = moved.empty() ? o.in_place_s : 0;
    for (const auto& mv : moved) end = std::max(end, mv.end());
    std::vector<double> label_end(m, -1);
    std::vector<task::Label> label(m);
    for (const auto* s : segs) {
      label[s->token.entity] = {s->token.action, s->token.target};
      label_end[s->token.entity] = end;  // in-place, and motions without their own end below
    }
    for (const auto& mv : moved) label_end[mv.entity] = mv.end();
    const size_t first_row = d.t.size();
    std::vector<task::Label> row_labels(m);
    for (size_t i = first_row;; ++i) {
      const double tau = static_cast<double>(i - first_row) * dt;
      if (tau > end + 1e-9) break;
      for (const auto& mv : moved) pos[mv.entity] = mv.at(tau);
      for (size_t e = 0; e < m; ++e) row_labels[e] = tau <= label_end[e] + 1e-9 ? label[e] : task::Label{};
      emit(row_labels);
    }
    gap();
  }
  rest(1.0);

  // The tracker: noise on every pose, and a dropped frame now and then holds the last one.
  std::vector<int> hold(m, 0);
  for (size_t i = 0; i < d.rows(); ++i)
    for (size_t e = 0; e < m; ++e) {
      if (i > 0 && hold[e] > 0) {
        --hold[e];
        d.positions[i][e] = d.positions[i - 1][e];
        continue;
      }
      if (i > 0 && rng.uniform() < o.hold_probability) {
        hold[e] = static_cast<int>(rng.index(static_cast<size_t>(o.hold_max_rows)));
        d.positions[i][e] = d.positions[i - 1][e];
        continue;
      }
      Vector2d& p = d.positions[i][e];
      p += o.noise_m * Vector2d(rng.normal(), rng.normal());
      p = {micrometres(p.x()), micrometres(p.y())};
    }
  d.analyze();
  return d;
}

double LabelScore::accuracy() const {
  const int denom = std::max(true_tokens, inferred_tokens);
  return denom == 0 ? 1.0 : static_cast<double>(matched) / denom;
}

void LabelScore::add(const LabelScore& o) {
  true_tokens += o.true_tokens;
  inferred_tokens += o.inferred_tokens;
  matched += o.matched;
  demos += o.demos;
  demos_exact += o.demos_exact;
  notes += o.notes;
  onset_error_s.insert(onset_error_s.end(), o.onset_error_s.begin(), o.onset_error_s.end());
  offset_error_s.insert(offset_error_s.end(), o.offset_error_s.begin(), o.offset_error_s.end());
}

LabelScore scoreLabels(const task::Demonstration& truth, const task::Demonstration& inferred, int notes) {
  LabelScore s;
  s.demos = 1;
  s.demos_exact = task::sameSteps(truth.steps, inferred.steps) ? 1 : 0;
  s.notes = notes;
  s.true_tokens = static_cast<int>(truth.segments.size());
  s.inferred_tokens = static_cast<int>(inferred.segments.size());
  std::vector<bool> used(inferred.segments.size(), false);
  for (const auto& ts : truth.segments)
    for (size_t j = 0; j < inferred.segments.size(); ++j) {
      const auto& is = inferred.segments[j];
      if (used[j] || is.token != ts.token || is.step != ts.step) continue;
      if (is.last_row < ts.first_row || is.first_row > ts.last_row) continue;  // another time
      used[j] = true;
      ++s.matched;
      s.onset_error_s.push_back(std::abs(inferred.t[is.first_row] - truth.t[ts.first_row]));
      s.offset_error_s.push_back(std::abs(inferred.t[is.last_row] - truth.t[ts.last_row]));
      break;
    }
  return s;
}

InferredDataset inferredDataset(const task::TaskDir& generated, const HumanMotionOptions& options, uint64_t seed) {
  InferredDataset out;
  out.truth.spec = out.inferred.spec = generated.spec;
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ULL + 0x1abe15ULL);
  for (const auto& d : generated.demos) out.truth.demos.push_back(humanMotion(d, generated.spec, options, rng));
  if (out.truth.demos.empty()) return out;
  const Example example = Example::fromDemonstration(out.truth.demos.front(), generated.spec);
  out.inferred.demos.push_back(out.truth.demos.front());
  for (size_t i = 1; i < out.truth.demos.size(); ++i) {
    task::Demonstration d = out.truth.demos[i];
    const Inference inf = inferLabels(d, generated.spec, &example);
    applyLabels(d, inf);
    out.score.add(scoreLabels(out.truth.demos[i], d, static_cast<int>(inf.notes.size())));
    out.inferred.demos.push_back(std::move(d));
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

}  // namespace ddace::label
