#include "ddace/label/inference.h"

#include "ddace/task/end_point.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ddace::label {

using Eigen::Vector2d;

SegmentationOptions SegmentationOptions::forTask(const task::TaskSpec& spec) {
  SegmentationOptions o;
  const double r = spec.arrival_radius;
  o.arrival_m = r;
  o.start_m = r / 2;
  o.still_m = r / 6;
  o.nudge_m = r;
  return o;
}

namespace {

/// How far from touching `mover`'s body at `end` is the nearest body standing on goal
/// `goal` or touching one that does (positions `where`); infinity when none stands there.
double touchOnGoal(const task::TaskSpec& spec, int mover, int goal, const Vector2d& end,
                   const std::vector<Vector2d>& where) {
  const double r = spec.arrival_radius;
  const int n = static_cast<int>(where.size());
  std::vector<bool> on(where.size(), false);
  for (int j = 0; j < n; ++j)
    on[j] = j != mover && j != goal && spec.footprint(j).obstacle && (where[j] - where[goal]).norm() <= r;
  std::vector<bool> cluster = on;
  for (int j = 0; j < n; ++j)
    for (int k = 0; k < n && !cluster[j]; ++k)
      cluster[j] = on[k] && j != mover && j != goal && spec.footprint(j).obstacle &&
                   (where[j] - where[k]).norm() <= spec.contactDistance(j, k) + r / 4;
  double best = std::numeric_limits<double>::infinity();
  for (int j = 0; j < n; ++j)
    if (cluster[j]) best = std::min(best, std::abs((end - where[j]).norm() - spec.contactDistance(mover, j)));
  return best;
}

/// How far from touching `mover`'s body at `end` is the nearest body of the crowd round
/// obstacle `target` (standing still): bodies that came while the motion ran (at `at_end`,
/// not at `where`: others sent to it in the same step) to touch it, or to touch one of the
/// crowd (a robot stopped behind another), if within `tolerance`; infinity when none is.
/// Touching, as a side reading: within `tolerance` of contact.
double touchOnCrowd(const task::TaskSpec& spec, int mover, int target, const Vector2d& end,
                    const std::vector<Vector2d>& where, const std::vector<Vector2d>& at_end, double tolerance) {
  const double r = spec.arrival_radius;
  double best = std::numeric_limits<double>::infinity();
  if ((at_end[target] - where[target]).norm() > r / 4) return best;  // a crowd gathers at a body that stays
  const int n = static_cast<int>(where.size());
  std::vector<bool> crowd(where.size(), false);
  crowd[target] = true;
  for (bool grew = true; grew;) {
    grew = false;
    for (int j = 0; j < n; ++j) {
      if (crowd[j] || j == mover || !spec.footprint(j).obstacle) continue;
      for (int k = 0; k < n && !crowd[j]; ++k) {
        const double joined = spec.contactDistance(j, k) + tolerance;
        crowd[j] = crowd[k] && (at_end[j] - at_end[k]).norm() <= joined && (where[j] - where[k]).norm() > joined;
      }
      grew = grew || crowd[j];
    }
  }
  for (int j = 0; j < n; ++j) {
    if (!crowd[j] || j == target) continue;
    const double gap = std::abs((end - at_end[j]).norm() - spec.contactDistance(mover, j));
    if (gap <= tolerance) best = std::min(best, gap);
  }
  return best;
}

}  // namespace

EndPoint endPoint(const task::TaskSpec& spec, int mover, const Vector2d& start, const Vector2d& end,
                  const std::vector<Vector2d>& where, const std::vector<bool>& candidates, int load,
                  const std::vector<Vector2d>* at_end, bool touching) {
  const double r = spec.arrival_radius;
  EndPoint ep;
  ep.nearest_m = std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, int>> arrived;  // (residual, entity)
  const task::EndPointModel bodies;             // nothing learned: the footprints decide
  for (size_t c = 0; c < where.size(); ++c) {
    if (!candidates[c] || static_cast<int>(c) == mover) continue;
    const int target = static_cast<int>(c);
    const double d = (end - where[c]).norm();
    if (d < ep.nearest_m) ep.nearest_m = d, ep.nearest = target;
    // The two readings: on the target's centre, or where the task's end-point rule puts the
    // end of this motion (task/end_point.h: at contact with an obstacle, behind a load).
    std::vector<task::Token> step = {{mover, "move", target}};
    if (load >= 0 && load != target) step.push_back({load, "move", target});
    const Vector2d rule = task::endPointFrom(start, where[c], task::endOffset(spec, bodies, step, 0));
    double residual = std::min(d, (end - rule).norm());
    // Two weaker readings, half the arrival radius worse than a perfect one (so the rule's
    // reading decides ties), of where a body already stood (generators.h, stepEndPositions):
    // touching an obstacle target from another side, or stopped on the way short of a goal
    // by up to the mover's diameter, touching the body on it.
    const task::Footprint mover_body = spec.footprint(mover);
    if (const double contact = spec.contactDistance(mover, target); contact > 0 && load < 0) {
      const double side = touching ? r / 4 : r / 2;
      if (std::abs(d - contact) <= side) residual = std::min(residual, std::abs(d - contact) + r / 2);
      // Others sent to it in the same step crowd round it: ending at one of them, from any
      // side, reads the target as a side touch does (the first body of the crowd it met).
      if (at_end) residual = std::min(residual, touchOnCrowd(spec, mover, target, end, where, *at_end, side) + r / 2);
    } else if (!spec.footprint(target).obstacle && load < 0 && (where[c] - start).norm() > task::kMinApproachM) {
      const Vector2d u = (where[c] - start).normalized();
      const double along = std::clamp((where[c] - end).dot(u), 0.0, 2 * mover_body.radius_m);
      residual = std::min(residual, (end - (where[c] - along * u)).norm() + r / 2);
      // A goal bodies stand on (one on it, others touching that one): touching any of them
      // from any side is a reading of the goal too, as good as the body's own side touch, so
      // a motion that ends there ties the goal with the body it touches.
      if (const double touch = touchOnGoal(spec, mover, c, end, at_end ? *at_end : where); touch <= r)
        residual = std::min(residual, touch + r / 4);
    }
    if (residual <= r) arrived.push_back({residual, target});
  }
  if (arrived.empty()) return ep;
  std::sort(arrived.begin(), arrived.end());
  ep.target = arrived[0].second;
  ep.residual = arrived[0].first;
  // End points closer than half the arrival radius in residual are a tie: the motion does
  // not say which one was meant.
  for (size_t i = 1; i < arrived.size(); ++i)
    if (arrived[i].first - arrived[0].first < r / 2) ep.tied.push_back(arrived[i].second);
  return ep;
}

void Motion::absorbClosest(const Motion& o) {
  for (size_t j = 0; j < min_distance.size(); ++j) {
    if (o.min_distance[j] >= min_distance[j]) continue;
    min_distance[j] = o.min_distance[j];
    closest_speed[j] = o.closest_speed[j];
    slow_near[j] = o.slow_near[j];
    closest_at[j] = o.closest_at[j];
    closest_row[j] = o.closest_row[j];
    closest_t[j] = o.closest_t[j];
    closest_scene[j] = o.closest_scene[j];
  }
}

void Motion::continueWith(const Motion& o) {
  off_row = o.off_row;
  off_t = o.off_t;
  end = o.end;
  end_dir = o.end_dir;
  at_offset = o.at_offset;
  leg_start = o.leg_start;
  for (size_t j = 0; j < max_distance.size(); ++j) max_distance[j] = std::max(max_distance[j], o.max_distance[j]);
  absorbClosest(o);
}

MotionSegmenter::MotionSegmenter(size_t entities, const SegmentationOptions& options) : o_(options), state_(entities) {}

void MotionSegmenter::row(double t, const std::vector<Vector2d>& positions) {
  history_.push_back({row_, t, positions});
  while (history_.size() > 1 && t - history_.front().t > o_.history_s) history_.pop_front();
  for (size_t e = 0; e < state_.size(); ++e) {
    EntityState& st = state_[e];
    const Vector2d& p = positions[e];
    if (!st.moving) {
      const double d = (p - st.anchor).norm();
      if (st.anchor_n == 0 || d <= 2 * o_.edge_m) {
        // The rest position: a running mean of the rows that differ from it by noise only
        // (bounded weight, so a slow drift of the tracker is followed; a slow start is not).
        if (st.anchor_n == 0) st.home = st.rest_from = p, st.anchor_t = t;
        st.anchor_n = std::min(st.anchor_n + 1, 100);
        st.anchor += (p - st.anchor) / st.anchor_n;
        // Held still_s beyond the still_s that set it: it came to rest here (a creep moves
        // the anchor sooner); held pause_s: it rests here (a nudge not put back).
        if (t - st.anchor_t >= 2 * o_.still_s) st.rest_from = st.anchor;
        if (t - st.anchor_t >= o_.pause_s) st.home = st.anchor;
      } else if (d > o_.start_m) {
        startMotion(e);
      } else if (Vector2d rest; stillAt(e, o_.still_m, rest) && (rest - st.anchor).norm() > o_.edge_m) {
        // Come to rest a little off (a nudge not put back exactly): rest there. Unless
        // that is farther than start_m from where it came to rest: it crept away, slower
        // than still_m in still_s (a slow start), from there.
        st.anchor = rest;
        st.anchor_n = 1;
        st.anchor_t = t;
        if ((rest - st.rest_from).norm() > o_.start_m) {
          st.anchor = st.rest_from;
          startMotion(e);
          st.motion.crept = true;
        }
      }
      continue;
    }
    trackDistances(st.motion, history_.size() - 1);
    Vector2d rest;
    size_t first = 0;
    if (stopped(e, rest, first)) endMotion(e, rest, first);
  }
  last_t_ = t;
  ++row_;
}

void MotionSegmenter::startMotion(size_t e) {
  EntityState& st = state_[e];
  // The onset: the last row still at rest (within edge_m of the rest position).
  size_t k = history_.size() - 1;
  while (k > 0 && (smoothed(k, e) - st.anchor).norm() > o_.edge_m) --k;
  // Sharper: when it left, extrapolated from how it sped up.
  // Not before the 5-row average says it was at rest (it reaches 2 rows ahead).
  if (const auto t0 = restTime(k, history_.size() - 1, e, st.anchor); t0 && *t0 >= history_[k >= 2 ? k - 2 : 0].t) {
    size_t j = k;
    while (j > 0 && history_[j].t > *t0 + 1e-9) --j;
    while (j + 1 < history_.size() && history_[j + 1].t <= *t0 + 1e-9) ++j;
    k = j;
  }
  const Sample& s = history_[k];
  Motion& m = st.motion;
  m = Motion{};
  m.entity = static_cast<int>(e);
  m.on_row = s.row;
  m.on_t = s.t;
  m.start = m.leg_start = st.anchor;
  m.rested_at = st.home;
  m.at_onset = s.p;
  m.max_distance.assign(s.p.size(), 0);
  m.min_distance.assign(s.p.size(), std::numeric_limits<double>::infinity());
  m.closest_speed.assign(s.p.size(), std::numeric_limits<double>::infinity());
  m.slow_near.assign(s.p.size(), {});
  m.closest_at.assign(s.p.size(), s.p[e]);
  m.closest_row.assign(s.p.size(), s.row);
  m.closest_t.assign(s.p.size(), s.t);
  m.closest_scene.assign(s.p.size(), s.p);
  const Eigen::Vector2d away = history_.back().p[e] - st.anchor;
  if (away.norm() > 0) m.start_dir = away.normalized();
  for (size_t i = k; i < history_.size(); ++i) trackDistances(m, i);
  st.moving = true;
}

bool MotionSegmenter::stillAt(size_t e, double within, Vector2d& rest) const {
  const double now = history_.back().t;
  size_t w = history_.size() - 1;
  while (w > 0 && now - history_[w - 1].t <= o_.still_s + 1e-9) --w;
  // Rows older than the window exist (it spans still_s), and it holds at least 3 rows.
  if (w == 0 || history_.size() - w < 3) return false;
  Vector2d mean = Vector2d::Zero();
  for (size_t i = w; i < history_.size(); ++i) mean += history_[i].p[e];
  mean /= static_cast<double>(history_.size() - w);
  for (size_t i = w; i < history_.size(); ++i)
    if ((history_[i].p[e] - mean).norm() > within) return false;
  rest = mean;
  return true;
}

bool MotionSegmenter::stopped(size_t e, Vector2d& rest, size_t& first) const {
  if (!stillAt(e, o_.still_m, rest)) return false;
  // The offset: the first row at rest after the last one clearly moving.
  size_t b = history_.size() - 1;
  while (b > 0 && (history_[b].p[e] - rest).norm() <= o_.still_m) --b;
  first = b + 1;
  while (first < history_.size() - 1 && (smoothed(first, e) - rest).norm() > o_.edge_m) ++first;
  // Sharper: when it arrived, extrapolated from how it slowed down.
  size_t from = first;
  while (from > 0 && (smoothed(from - 1, e) - rest).norm() <= o_.start_m) --from;
  if (const auto t1 = restTime(from, first, e, rest);
      t1 && *t1 <= history_[std::min(first + 2, history_.size() - 1)].t) {
    size_t j = first;
    while (j > from && history_[j - 1].t >= *t1 - 1e-9) --j;
    while (j + 1 < history_.size() && history_[j].t < *t1 - 1e-9) ++j;
    first = j;
  }
  return true;
}

void MotionSegmenter::trackDistances(Motion& m, size_t i) const {
  // A held pose (the tracker repeating the last one for a dropped frame: the same numbers
  // exactly) lags a moving entity; such a row says nothing about how far apart two are.
  auto held = [&](size_t e) { return i > 0 && history_[i].p[e] == history_[i - 1].p[e]; };
  if (held(m.entity)) return;
  const auto& p = history_[i].p;
  for (size_t j = 0; j < p.size(); ++j) {
    const double d = (p[m.entity] - p[j]).norm();
    if (!held(j)) m.max_distance[j] = std::max(m.max_distance[j], d);
    if (d < m.min_distance[j]) {
      m.min_distance[j] = d;
      m.closest_at[j] = p[m.entity];
      m.closest_row[j] = history_[i].row;
      m.closest_t[j] = history_[i].t;
      m.closest_scene[j] = p;
    }
    // The slowest it went while closest (within still_m of the closest distance); a held
    // pose of a resting entity is where it rests.
    auto& front = m.slow_near[j];  // by distance, speeds falling
    const double within = m.min_distance[j] + o_.still_m;
    while (!front.empty() && front.back().first > within) front.pop_back();
    const double v = speed(i, m.entity);
    auto at = std::lower_bound(front.begin(), front.end(), std::pair{d, -1.0});
    if (d <= within && (at == front.begin() || std::prev(at)->second > v)) {
      at = front.insert(at, {d, v});
      front.erase(std::remove_if(std::next(at), front.end(), [&](const auto& e) { return e.second >= v; }),
                  front.end());
    }
    m.closest_speed[j] = front.empty() ? std::numeric_limits<double>::infinity() : front.back().second;
  }
}

std::optional<double> MotionSegmenter::restTime(size_t from, size_t to, size_t e, const Vector2d& rest) const {
  // At constant acceleration the distance from rest grows with the square of the time
  // since (or until) rest: its square root is a line in time, zero at the moment of rest.
  double n = 0, st = 0, sr = 0, stt = 0, str = 0;
  const double t_ref = history_[from].t;
  for (size_t i = from; i <= to; ++i) {
    // Raw positions (an average over rows would start the rise before the motion did),
    // far enough from rest to be above the tracker's noise.
    const double d = (history_[i].p[e] - rest).norm();
    if (d < 2 * o_.edge_m || d > o_.start_m) continue;
    const double t = history_[i].t - t_ref, r = std::sqrt(d);
    n += 1, st += t, sr += r, stt += t * t, str += t * r;
  }
  const double det = n * stt - st * st;
  if (n < 3 || det <= 0) return std::nullopt;
  const double a = (n * str - st * sr) / det, b = (sr - a * st) / n;
  if (a == 0) return std::nullopt;
  const double t0 = t_ref - b / a;
  // Only a correction within the rows it was fitted on and a second around them.
  if (!(t0 >= history_[from].t - 1.0 && t0 <= history_[to].t + 1.0)) return std::nullopt;
  return t0;
}

double MotionSegmenter::speed(size_t i, size_t e) const {
  // Over the last still_s / 2 (shorter: noise; longer: a brief stop is averaged away).
  size_t k = i;
  while (k > 0 && history_[i].t - history_[k].t < o_.still_s / 2) --k;
  const double dt = history_[i].t - history_[k].t;
  return dt > 0 ? (history_[i].p[e] - history_[k].p[e]).norm() / dt : 0;
}

Vector2d MotionSegmenter::smoothed(size_t i, size_t e) const {
  const size_t lo = i >= 2 ? i - 2 : 0, hi = std::min(i + 2, history_.size() - 1);
  Vector2d sum = Vector2d::Zero();
  for (size_t j = lo; j <= hi; ++j) sum += history_[j].p[e];
  return sum / static_cast<double>(hi - lo + 1);
}

void MotionSegmenter::endMotion(size_t e, const Vector2d& rest, size_t first) {
  EntityState& st = state_[e];
  Motion& m = st.motion;
  const Sample& s = history_[std::max<size_t>(first, 0)];
  m.off_row = std::max(s.row, m.on_row);
  m.off_t = std::max(s.t, m.on_t);
  m.end = rest;
  m.at_offset = s.p;
  m.whole_off_row = m.off_row;
  m.whole_off_t = m.off_t;
  // The heading it came in: from the last row start_m away from where it stopped.
  for (size_t i = history_.size(); i-- > 0;) {
    const Vector2d in = rest - history_[i].p[e];
    if (in.norm() > o_.start_m) {
      m.end_dir = in.normalized();
      break;
    }
  }
  if ((rest - m.start).norm() >= o_.nudge_m) st.home = rest;
  done_.push_back(std::move(m));
  st.moving = false;
  st.anchor = st.rest_from = rest;
  st.anchor_n = 1;
  st.anchor_t = history_.back().t;
}

void MotionSegmenter::finish() {
  finished_ = true;
  if (history_.empty()) return;
  for (size_t e = 0; e < state_.size(); ++e)
    if (state_[e].moving) endMotion(e, history_.back().p[e], history_.size() - 1);
  for (auto& st : state_) st.moving = false;
}

std::vector<Motion> MotionSegmenter::take() {
  std::vector<Motion> out;
  out.swap(done_);
  return out;
}

MotionSegmenter::Horizon MotionSegmenter::horizon() const {
  if (finished_) return {std::numeric_limits<int>::max(), std::numeric_limits<double>::infinity()};
  if (history_.empty()) return {};
  Horizon h{history_.front().row, history_.front().t};
  for (const auto& st : state_)
    if (st.moving && st.motion.on_row < h.row) h = {st.motion.on_row, st.motion.on_t};
  return h;
}

bool MotionSegmenter::allResting() const {
  for (const auto& st : state_)
    if (st.moving) return false;
  return true;
}

}  // namespace ddace::label
