#include "ddace/label/human_motion.h"

#include "ddace/common/error.h"
#include "ddace/tasks/generators.h"

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

using Profile = HumanMotionOptions::Profile;

/// The fraction of its path a motion of `profile` has covered at time fraction u (Eased:
/// none here, the generated timing is kept).
double covered(Profile profile, double u) {
  switch (profile) {
    case Profile::Constant:
      return u;
    case Profile::Brisk:
      return 1 - (1 - u) * (1 - u);
    case Profile::Late:
      return u * u;
    default:
      return u;
  }
}

/// One motion of a step as the person makes it: the generated path, re-timed, and moved
/// from where the entity really is (`from_shift` off the path's start) to `to_shift` off
/// the path's end.
struct Moved {
  int entity = -1;
  std::vector<Vector2d> path;                               ///< the generated positions, evenly in time
  double delay = 0, duration = 0, pause_at = 0, pause = 0;  ///< seconds from the step's start; pause_at in [0, 1]
  Profile profile = Profile::Eased;
  Vector2d from_shift = Vector2d::Zero(), to_shift = Vector2d::Zero();
  std::vector<double> arc;  ///< [i] path length up to path[i]
  double end() const { return delay + duration + pause; }
  void measure() {
    arc.assign(path.size(), 0);
    for (size_t i = 1; i < path.size(); ++i) arc[i] = arc[i - 1] + (path[i] - path[i - 1]).norm();
  }
  /// The point at index position u (fractional) and its fraction of the path's length.
  Vector2d atIndex(double u, double& fraction) const {
    const size_t i = std::min(static_cast<size_t>(u), path.size() - 1);
    const double f = i + 1 < path.size() ? u - static_cast<double>(i) : 0;
    const double len = arc.back() > 0 ? arc.back() : 1;
    fraction = (i + 1 < path.size() ? arc[i] + f * (arc[i + 1] - arc[i]) : arc.back()) / len;
    return i + 1 < path.size() ? Vector2d(path[i] + f * (path[i + 1] - path[i])) : path.back();
  }
  /// How far along its generated timing the motion is at tau, [0, 1] of its rows.
  double progress(double tau) const {
    double q = tau - delay;
    if (q <= 0) return 0;
    if (pause > 0 && q > pause_at * duration) q = std::max(pause_at * duration, q - pause);
    const double u = std::min(q / duration, 1.0);
    if (profile == Profile::Eased || path.size() < 2) return u;
    // The row whose arc length is the profile's.
    const double want = covered(profile, u) * arc.back();
    const size_t i = static_cast<size_t>(std::lower_bound(arc.begin(), arc.end(), want) - arc.begin());
    double x = static_cast<double>(std::min(i, path.size() - 1));
    if (i > 0 && i < path.size() && arc[i] > arc[i - 1]) x = (i - 1) + (want - arc[i - 1]) / (arc[i] - arc[i - 1]);
    return x / static_cast<double>(path.size() - 1);
  }
  /// Where it is at `progress` (of its rows), moved from from_shift to to_shift.
  Vector2d place(double progress) const {
    double fraction = 0;
    const Vector2d p = atIndex(progress * static_cast<double>(path.size() - 1), fraction);
    return p + (1 - fraction) * from_shift + fraction * to_shift;
  }
  /// The heading of the path's last centimetre.
  Vector2d endHeading() const {
    size_t i = path.size() - 1;
    while (i > 0 && (path.back() - path[i]).norm() < 0.01) --i;
    const Vector2d d = path.back() - path[i];
    return d.norm() > 1e-9 ? Vector2d(d.normalized()) : Vector2d::UnitX();
  }
};

/// Makes one demonstration as a person moves the robots (humanMotion): row by row, step by
/// step, then seen through the tracker.
class Demonstrator {
 public:
  Demonstrator(const task::Demonstration& clean, const task::TaskSpec& spec, const HumanMotionOptions& o,
               SplitMix64& rng)
      : clean_(clean), spec_(spec), o_(o), rng_(rng), m_(spec.entities.size()), dt_(1.0 / o.rate_hz) {
    d_.source = clean.source;
    d_.has_label_columns = clean.has_label_columns;
    pos_ = clean.positions.front();
  }

  task::Demonstration run() {
    rest(rng_.uniform(0.5, 1.0));
    for (size_t k = 0; k < clean_.steps.size(); ++k) {
      playStep(static_cast<int>(k));
      gap();
    }
    rest(1.0);
    track();
    d_.analyze();
    return std::move(d_);
  }

 private:
  void emit(const std::vector<task::Label>& labels) {
    d_.t.push_back(static_cast<double>(d_.t.size()) / o_.rate_hz);
    d_.positions.push_back(pos_);
    d_.labels.push_back(labels);
  }
  void rest(double seconds) {
    const std::vector<task::Label> idle(m_);
    for (int i = 0, n = static_cast<int>(std::round(seconds / dt_)); i < n; ++i) emit(idle);
  }

  /// Between two steps: a person's pause, perhaps bumping a robot and putting it back.
  void gap() {
    const double g = rng_.uniform(o_.gap_min_s, o_.gap_max_s);
    std::vector<int> robots;
    for (size_t e = 0; e < m_; ++e)
      if (spec_.entities[e].kind == task::EntityKind::Robot) robots.push_back(static_cast<int>(e));
    if (robots.empty() || rng_.uniform() >= o_.nudge_probability) return rest(g);
    const int r = robots[rng_.index(robots.size())];
    if (o_.nudge_max_m <= 0) return rest(g);
    const Vector2d home = pos_[r];
    const double a = rng_.uniform(0, 2 * M_PI), dist = rng_.uniform(o_.nudge_min_m, o_.nudge_max_m);
    const Vector2d away = home + dist * Vector2d(std::cos(a), std::sin(a));
    const std::vector<task::Label> idle(m_);
    rest(0.3);
    const int n = static_cast<int>(std::round(0.25 / dt_));
    for (int i = 1; i <= n; ++i) pos_[r] = home + (away - home) * i / n, emit(idle);
    rest(0.3);
    for (int i = 1; i <= n; ++i) pos_[r] = away + (home - away) * i / n, emit(idle);
    rest(std::max(o_.gap_min_s, g - 1.1));  // the hand goes on to the next robot
  }

  /// A robot motion that carries a load (an object of its step with the same action and
  /// target): the load ends it.
  bool carries(const task::Segment& seg) const {
    for (const auto& other : clean_.segments)
      if (other.step == seg.step && other.token.entity != seg.token.entity && other.token.action == seg.token.action &&
          other.token.target == seg.token.target && spec_.entities[other.token.entity].kind == task::EntityKind::Object)
        return true;
    return false;
  }

  /// Where a robot sent to goal `target` that a body stands on ends: touching the body
  /// nearest its generated end, turned about it; zero when no body is there.
  Vector2d besideShift(const task::Segment& seg, const std::vector<Vector2d>& path, const Vector2d& heading) {
    const int mover = seg.token.entity;
    const auto& at_end = clean_.positions[seg.last_row];
    if ((path.back() - at_end[seg.token.target]).norm() <= spec_.arrival_radius) return Vector2d::Zero();
    int body = -1;
    double best = 1e9;
    for (size_t j = 0; j < spec_.entities.size(); ++j) {
      const double d = (at_end[j] - path.back()).norm();
      if (static_cast<int>(j) != mover && spec_.footprint(static_cast<int>(j)).obstacle && d < best)
        best = d, body = static_cast<int>(j);
    }
    if (body < 0) return Vector2d::Zero();
    const Vector2d at = at_end[body];
    const double turn = rng_.uniform(-o_.beside_max_rad, o_.beside_max_rad);
    const Vector2d from = (path.back() - at).norm() > 1e-9 ? Vector2d((path.back() - at).normalized()) : -heading;
    const Vector2d turned(std::cos(turn) * from.x() - std::sin(turn) * from.y(),
                          std::sin(turn) * from.x() + std::cos(turn) * from.y());
    return Vector2d(at + spec_.contactDistance(mover, body) * turned - path.back());
  }

  /// Where a motion of a robot that carries nothing ends, off its generated end: short of
  /// contact with a body it touches, beside a goal another body stands on.
  Vector2d endShift(const task::Segment& seg, const std::vector<Vector2d>& path, const Vector2d& heading) {
    const int mover = seg.token.entity, target = seg.token.target;
    if (spec_.entities[mover].kind != task::EntityKind::Robot || target < 0 || carries(seg)) return Vector2d::Zero();
    const task::EntityKind kind = spec_.entities[target].kind;
    if (kind != task::EntityKind::Goal && o_.contact_gap_max_m > 0)
      return Vector2d(-rng_.uniform(o_.contact_gap_min_m, o_.contact_gap_max_m) * heading);
    if (kind == task::EntityKind::Goal && o_.beside_max_rad > 0) return besideShift(seg, path, heading);
    return Vector2d::Zero();
  }

  /// The person's timing of a motion that follows no carrier.
  void time(Moved& mv, const task::Segment& s, const std::vector<Vector2d>& path) {
    const double generated = clean_.t[s.last_row] - clean_.t[s.first_row];
    mv.delay = rng_.uniform(0, o_.onset_spread_s);
    mv.duration = generated / rng_.uniform(o_.speed_min, o_.speed_max);
    if (rng_.uniform() < o_.pause_probability)
      mv.pause_at = rng_.uniform(0.3, 0.7), mv.pause = rng_.uniform(o_.pause_min_s, o_.pause_max_s);
    mv.profile = o_.profile != Profile::Mixed ? o_.profile : static_cast<Profile>(rng_.index(4));
    mv.to_shift = endShift(s, path, mv.endHeading());
  }

  /// The motions of step k as the person makes them; leader[i]: the index of the motion
  /// motion i follows (a load), or -1.
  std::vector<Moved> plan(const std::vector<const task::Segment*>& segs, std::vector<int>& leader) {
    std::vector<Moved> moved;
    std::vector<task::Token> moved_tokens;  // [moved]
    for (const auto* s : segs) {
      if (!s->token.isMotion()) continue;
      auto path = clean_.segmentPath(*s);
      if ((path.back() - path.front()).norm() < 1e-3) continue;
      Moved mv;
      mv.entity = s->token.entity;
      mv.path = path;
      mv.measure();
      mv.from_shift = pos_[mv.entity] - path.front();
      // A load moves with its carrier (task::carriedLoad: a robot of the step with the same
      // action and target; its path runs in front of the carrier's, docs/task-format.md).
      int follows = -1;
      if (spec_.entities[mv.entity].kind == task::EntityKind::Object)
        for (size_t j = 0; j < moved.size(); ++j)
          if (spec_.entities[moved[j].entity].kind == task::EntityKind::Robot &&
              moved_tokens[j].action == s->token.action && moved_tokens[j].target == s->token.target)
            follows = static_cast<int>(j);
      if (follows >= 0) {
        const Moved& l = moved[follows];
        mv.delay = l.delay, mv.duration = l.duration, mv.pause_at = l.pause_at, mv.pause = l.pause;
        mv.profile = l.profile;
      } else {
        time(mv, *s, path);
      }
      moved.push_back(mv);
      moved_tokens.push_back(s->token);
      leader.push_back(follows);
    }
    // The first motion starts the step.
    double first = 1e9;
    for (const auto& mv : moved) first = std::min(first, mv.delay);
    for (auto& mv : moved) mv.delay -= first;
    return moved;
  }

  /// Step k's rows, labelled with the true tokens (each to the end of its own motion).
  void playStep(int k) {
    std::vector<const task::Segment*> segs;
    for (const auto& s : clean_.segments)
      if (s.step == k) segs.push_back(&s);
    std::vector<int> leader;
    const std::vector<Moved> moved = plan(segs, leader);
    double end = moved.empty() ? o_.in_place_s : 0;
    for (const auto& mv : moved) end = std::max(end, mv.end());
    std::vector<double> label_begin(m_, 0), label_end(m_, -1);
    std::vector<task::Label> label(m_);
    for (const auto* s : segs) {
      label[s->token.entity] = {s->token.action, s->token.target};
      label_end[s->token.entity] = end;  // in-place, and motions without their own end below
    }
    for (const auto& mv : moved) {
      label_end[mv.entity] = mv.end();
      if (o_.label_at_own_onset) label_begin[mv.entity] = mv.delay;
    }
    const size_t first_row = d_.t.size();
    std::vector<task::Label> row_labels(m_);
    for (size_t i = first_row;; ++i) {
      const double tau = static_cast<double>(i - first_row) * dt_;
      if (tau > end + 1e-9) break;
      // A load keeps to its carrier's timing (their generated rows go together).
      for (size_t j = 0; j < moved.size(); ++j)
        pos_[moved[j].entity] = moved[j].place(moved[leader[j] >= 0 ? leader[j] : j].progress(tau));
      for (size_t e = 0; e < m_; ++e)
        row_labels[e] = tau >= label_begin[e] - 1e-9 && tau <= label_end[e] + 1e-9 ? label[e] : task::Label{};
      emit(row_labels);
    }
  }

  /// The tracker: noise on every pose, and a dropped frame now and then holds the last one.
  void track() {
    std::vector<int> hold(m_, 0);
    for (size_t i = 0; i < d_.rows(); ++i)
      for (size_t e = 0; e < m_; ++e) {
        if (i > 0 && hold[e] > 0) {
          --hold[e];
          d_.positions[i][e] = d_.positions[i - 1][e];
          continue;
        }
        if (i > 0 && rng_.uniform() < o_.hold_probability) {
          hold[e] = static_cast<int>(rng_.index(static_cast<size_t>(o_.hold_max_rows)));
          d_.positions[i][e] = d_.positions[i - 1][e];
          continue;
        }
        Vector2d& p = d_.positions[i][e];
        p += o_.noise_m * Vector2d(rng_.normal(), rng_.normal());
        p = {micrometres(p.x()), micrometres(p.y())};
      }
  }

  const task::Demonstration& clean_;
  const task::TaskSpec& spec_;
  const HumanMotionOptions& o_;
  SplitMix64& rng_;
  const size_t m_;
  const double dt_;
  task::Demonstration d_;
  std::vector<Vector2d> pos_;  ///< where every entity is now
};

}  // namespace

task::Demonstration humanMotion(const task::Demonstration& clean, const task::TaskSpec& spec,
                                const HumanMotionOptions& o, SplitMix64& rng) {
  return Demonstrator(clean, spec, o, rng).run();
}

std::vector<DemonstrationStyle> demonstrationStyles() {
  HumanMotionOptions calm;
  calm.onset_spread_s = 0;
  calm.speed_min = calm.speed_max = 1;
  calm.pause_probability = 0;
  calm.nudge_probability = 0;
  calm.gap_min_s = calm.gap_max_s = 1.0;
  calm.noise_m = 0;
  calm.hold_probability = 0;
  std::vector<DemonstrationStyle> styles;
  auto add = [&](const std::string& name, const std::string& description, auto change) {
    HumanMotionOptions o = calm;
    change(o);
    styles.push_back({name, description, o});
  };
  add("calm", "steps 1 s apart, the robots of a step start together, generated speed, no camera", [](auto&) {});
  add("pause", "0-1 s between steps", [](HumanMotionOptions& o) { o.gap_min_s = 0, o.gap_max_s = 1; });
  add("onset", "each robot of a step starts 0-1 s after the first",
      [](HumanMotionOptions& o) { o.onset_spread_s = 1; });
  add("speed", "0.5-2x speed, constant, brisk, late-braking or eased, a pause on the way in 3 of 10",
      [](HumanMotionOptions& o) {
        o.speed_min = 0.5, o.speed_max = 2, o.profile = Profile::Mixed;
        o.pause_probability = 0.3;
      });
  add("contact", "a robot sent to a body stops 0-1 cm short of touching it",
      [](HumanMotionOptions& o) { o.contact_gap_min_m = 0, o.contact_gap_max_m = 0.01; });
  add("occupied", "a robot sent to a goal a body stands on ends touching that body from another side (up to 60 deg)",
      [](HumanMotionOptions& o) { o.beside_max_rad = M_PI / 3; });
  add("bump", "after every step a resting robot is bumped 1-3 cm and put back",
      [](HumanMotionOptions& o) { o.nudge_probability = 1, o.nudge_min_m = 0.01, o.nudge_max_m = 0.03; });
  add("camera", "1.5 mm noise, 5 % of frames dropped (held)",
      [](HumanMotionOptions& o) { o.noise_m = 0.0015, o.hold_probability = 0.03, o.hold_max_rows = 4; });
  HumanMotionOptions all;
  for (const auto& s : styles) {
    const HumanMotionOptions& o = s.options;
    if (s.name == "pause") all.gap_min_s = o.gap_min_s, all.gap_max_s = o.gap_max_s;
    if (s.name == "onset") all.onset_spread_s = o.onset_spread_s;
    if (s.name == "speed")
      all.speed_min = o.speed_min, all.speed_max = o.speed_max, all.profile = o.profile,
      all.pause_probability = o.pause_probability;
    if (s.name == "contact") all.contact_gap_min_m = o.contact_gap_min_m, all.contact_gap_max_m = o.contact_gap_max_m;
    if (s.name == "occupied") all.beside_max_rad = o.beside_max_rad;
    if (s.name == "bump")
      all.nudge_probability = o.nudge_probability, all.nudge_min_m = o.nudge_min_m, all.nudge_max_m = o.nudge_max_m;
    if (s.name == "camera")
      all.noise_m = o.noise_m, all.hold_probability = o.hold_probability, all.hold_max_rows = o.hold_max_rows;
  }
  styles.push_back({"all", "all of the above at once", all});
  return styles;
}

DemonstrationStyle demonstrationStyle(const std::string& name) {
  for (const auto& s : demonstrationStyles())
    if (s.name == name) return s;
  throw Error("no demonstration style '" + name +
              "' (calm, pause, onset, speed, contact, occupied, bump, camera, all)");
}

uint64_t styleSeed(uint64_t seed, const std::string& name) {
  const auto all = demonstrationStyles();
  for (size_t k = 0; k < all.size(); ++k)
    if (all[k].name == name) return seed + 17 * k;
  return seed;
}

task::TaskDir occupiedGoalFamily(int demos, uint64_t seed) {
  tasks::GeneratorOptions o;
  o.family = "fetch";
  o.demos = demos;
  o.seed = seed;
  task::TaskDir dir = tasks::generate(o);
  const int g1 = dir.spec.entityIndex("G1");
  for (auto& d : dir.demos) {
    std::vector<tasks::PlannedStep> steps;
    for (const auto& step : d.steps) {
      tasks::PlannedStep planned;
      for (const auto& t : step.tokens) planned.push_back({t, {}, 0});
      steps.push_back(planned);
    }
    // The last step, [O:move:F], goes to G1 instead.
    for (auto& t : steps.back()) t.token.target = g1;
    const std::string source = d.source;
    d = tasks::simulateSteps(dir.spec, d.positions.front(), steps);
    d.source = source;
  }
  dir.spec.name = kOccupiedGoalFamily;
  return dir;
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
  wrong += o.wrong, listed += o.listed, wrong_listed += o.wrong_listed;
  demos_wrong += o.demos_wrong, demos_wrong_listed += o.demos_wrong_listed;
  for (const auto& [kind, n] : o.listed_by_doubt) listed_by_doubt[kind][0] += n[0], listed_by_doubt[kind][1] += n[1];
  onset_error_s.insert(onset_error_s.end(), o.onset_error_s.begin(), o.onset_error_s.end());
  offset_error_s.insert(offset_error_s.end(), o.offset_error_s.begin(), o.offset_error_s.end());
}

double LabelScore::wrongListed() const {
  return wrong == 0 ? 1.0 : static_cast<double>(wrong_listed) / wrong;
}
double LabelScore::listedWrong() const {
  return listed == 0 ? 0.0 : static_cast<double>(wrong_listed) / listed;
}

std::string doubtKind(const std::string& message) {
  for (const char* words : {"stopped halfway", "ended between", "stopped at the crowd", "nearly stopped at",
                            "where the example's step", "moved alone", "no motion of the kind",
                            "moved again in the same step", "again, where its last motion ended", "in-place", "goal "})
    if (message.find(words) != std::string::npos) return words;
  return "other";
}

LabelScore scoreLabels(const task::Demonstration& truth, const task::Demonstration& inferred,
                       const Inference& inference) {
  LabelScore s;
  s.demos = 1;
  s.demos_exact = task::sameSteps(truth.steps, inferred.steps) ? 1 : 0;
  s.notes = static_cast<int>(inference.notes.size());
  s.true_tokens = static_cast<int>(truth.segments.size());
  s.inferred_tokens = static_cast<int>(inferred.segments.size());
  std::vector<bool> used(inferred.segments.size(), false);
  for (const auto& ts : truth.segments)
    for (size_t j = 0; j < inferred.segments.size(); ++j) {
      const auto& is = inferred.segments[j];
      if (used[j] || is.token != ts.token || is.step != ts.step) continue;
      // Another time; an in-place action leaves no trace in motion: any rows of its step's
      // still time are as right (the scene does not change there).
      if (ts.token.isMotion() && (is.last_row < ts.first_row || is.first_row > ts.last_row)) continue;
      used[j] = true;
      ++s.matched;
      s.onset_error_s.push_back(std::abs(inferred.t[is.first_row] - truth.t[ts.first_row]));
      s.offset_error_s.push_back(std::abs(inferred.t[is.last_row] - truth.t[ts.last_row]));
      break;
    }
  for (size_t j = 0; j < inferred.segments.size(); ++j) {
    const auto& is = inferred.segments[j];
    bool unsure = false;
    std::string doubt;
    for (const auto& step : inference.steps)
      for (const auto& t : step.tokens)
        if (!unsure && t.unsure && t.token.entity == is.token.entity && t.first_row <= is.last_row &&
            t.last_row >= is.first_row)
          unsure = true, doubt = t.doubt;
    if (unsure) {
      auto& n = s.listed_by_doubt[doubtKind(doubt)];
      ++n[0], n[1] += !used[j];
    }
    s.listed += unsure;
    s.wrong += !used[j];
    s.wrong_listed += unsure && !used[j];
  }
  // A demonstration that lost a token is wrong even when every token it has is right.
  const bool wrong = s.wrong > 0 || s.matched < s.true_tokens;
  s.demos_wrong = wrong;
  s.demos_wrong_listed = wrong && (s.listed > 0 || !inference.notes.empty());
  return s;
}

InferredDataset inferredDataset(const task::TaskDir& generated, const HumanMotionOptions& options, uint64_t seed) {
  InferredDataset out;
  out.truth.spec = out.inferred.spec = generated.spec;
  SplitMix64 rng(seed * 0x9E3779B97F4A7C15ULL + 0x1abe15ULL);
  for (const auto& d : generated.demos) out.truth.demos.push_back(humanMotion(d, generated.spec, options, rng));
  task::groupStepsAcrossDemonstrations(out.truth);
  if (out.truth.demos.empty()) return out;
  const Example example = Example::fromDemonstration(out.truth.demos.front(), generated.spec);
  out.inferred.demos.push_back(out.truth.demos.front());
  out.notes.emplace_back();
  for (size_t i = 1; i < out.truth.demos.size(); ++i) {
    task::Demonstration d = out.truth.demos[i];
    const Inference inf = inferLabels(d, generated.spec, &example);
    applyLabels(d, inf);
    out.score.add(scoreLabels(out.truth.demos[i], d, inf));
    out.notes.push_back(inf.notes);
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
