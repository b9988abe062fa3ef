#include "ddace/label/label.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>

#include "ddace/common/error.h"
#include "ddace/task/end_point.h"

namespace ddace::label {

using Eigen::Vector2d;

namespace {

std::string kindOf(const task::Entity& e, bool typed) {
  std::string s = task::toString(e.kind);
  if (typed && !e.type.empty()) s += "/" + e.type;
  return s;
}

std::string key(const task::TaskSpec& spec, int mover, int target, int load, bool typed) {
  std::string s =
      kindOf(spec.entities[mover], typed) + ">" + (target >= 0 ? kindOf(spec.entities[target], typed) : "none");
  if (load == 1) s += "+load";
  if (load == 2) s += "+carried";
  return s;
}

/// A kind as a tie tells it: with `bodies`, every kind but a goal is a body.
std::string kindClass(task::EntityKind kind, bool bodies) {
  return bodies && kind != task::EntityKind::Goal ? "body" : task::toString(kind);
}

/// "goal,robot": the kinds (classes) among `entities`, sorted, each once.
std::string tiedKinds(const task::TaskSpec& spec, const std::vector<int>& entities, bool bodies) {
  std::set<std::string> kinds;
  for (int e : entities) kinds.insert(kindClass(spec.entities[e].kind, bodies));
  std::string s;
  for (const auto& k : kinds) s += (s.empty() ? "" : ",") + k;
  return s;
}

std::string namesOf(const task::TaskSpec& spec, const std::vector<int>& entities) {
  std::string names;
  for (int c : entities) names += (names.empty() ? "" : " and ") + spec.entities[c].name;
  return names;
}

std::string metres(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

}  // namespace

std::string kindKey(const task::TaskSpec& spec, int mover, int target, int load) {
  return key(spec, mover, target, load, true);
}
std::string coarseKindKey(const task::TaskSpec& spec, int mover, int target, int load) {
  return key(spec, mover, target, load, false);
}

Labeller::Labeller(const task::TaskSpec& spec, const Example* example)
    : spec_(spec),
      example_(example),
      options_(SegmentationOptions::forTask(spec)),
      segmenter_(spec.entities.size(), options_),
      next_check_t_(std::numeric_limits<double>::infinity()),
      ex_inplace_before_(1),
      alignment_(example ? Alignment::Open : Alignment::NotAligned),
      last_arrival_(spec.entities.size()) {
  if (!example_) return;
  for (const auto& s : example_->steps) {
    const bool motion =
        std::any_of(s.tokens.begin(), s.tokens.end(), [](const task::Token& t) { return t.isMotion(); });
    for (const auto& t : s.tokens) ex_has_inplace_ = ex_has_inplace_ || !t.isMotion();
    if (motion) {
      ex_motion_.push_back(&s);
      ex_inplace_before_.emplace_back();
    } else {
      ex_inplace_before_.back().push_back(&s);
    }
  }
}

void Labeller::row(double t, const std::vector<Vector2d>& positions) {
  segmenter_.row(t, positions);
  std::vector<Motion> found = segmenter_.take();
  const bool arrived = !found.empty();
  if (arrived) arrive(std::move(found));
  if (arrived || segmenter_.horizon().t > next_check_t_) decide(false);
}

Inference Labeller::take() {
  Inference out;
  std::swap(out, out_);
  std::stable_sort(out.notes.begin(), out.notes.end(), [](const Note& a, const Note& b) { return a.row < b.row; });
  return out;
}

Inference Labeller::finish() {
  segmenter_.finish();
  arrive(segmenter_.take());
  decide(true);
  if (partial_) {
    Group last = std::move(*partial_);
    partial_.reset();
    place(std::move(last));
  }
  if (alignment_ == Alignment::Open) settle(held_.size() == ex_motion_.size());
  if (alignment_ == Alignment::Aligned) placeInPlace(ex_inplace_before_.back(), prev_off_ + 1, segmenter_.rows() - 1);
  // Fewer steps than the example's (a motion missed, or steps run together where no step's
  // movers told): no token to list, but the demonstration is not to be used unchecked.
  if (example_ && emitted_groups_ < ex_motion_.size())
    note(std::max(segmenter_.rows() - 1, 0),
         "the demonstration has " + std::to_string(emitted_groups_) + " step(s) of motion where the example" +
             (example_->source.empty() ? "" : " " + example_->source) + " has " + std::to_string(ex_motion_.size()) +
             " (a motion missed, or two steps run together?): check its steps");
  return take();
}

void Labeller::arrive(std::vector<Motion> found) {
  const auto& E = spec_.entities;
  for (auto& m : found) {
    // A goal is a mark on the table: its motion (a print pushed aside) is no token; one
    // less than nudge_m is the tracker's or a hand's, not reported.
    if (E[m.entity].kind == task::EntityKind::Goal && (m.end - m.start).norm() < options_.nudge_m) continue;
    if (E[m.entity].kind == task::EntityKind::Goal)
      note(m.on_row, "goal " + E[m.entity].name + " moved " + metres((m.end - m.start).norm()) +
                         " m; a goal does not act, its motion is no token (check the marker)");
    else pending_.push_back(std::move(m));
  }
}

// Entities that moved with a motion all the way (at one place with it, task::togetherDistance:
// as the end-point rule reads a carrier and its load): its loads or carrier.
bool Labeller::staysWith(const Motion& m, int j) const {
  return m.max_distance[j] <= task::togetherDistance(spec_, m.entity, j) &&
         (m.at_offset[j] - m.at_onset[j]).norm() >= options_.nudge_m;
}

bool Labeller::sweptBy(const Motion& o, const Motion& r) const {
  return spec_.entities[o.entity].kind == task::EntityKind::Object &&
         spec_.entities[r.entity].kind == task::EntityKind::Robot && r.on_t <= o.off_t && o.on_t <= r.off_t &&
         o.max_distance[r.entity] <= task::togetherDistance(spec_, o.entity, r.entity);
}

std::vector<bool> Labeller::candidatesOf(const Motion& m) const {
  std::vector<bool> c(spec_.entities.size(), true);
  for (size_t j = 0; j < c.size(); ++j) c[j] = static_cast<int>(j) != m.entity && !staysWith(m, static_cast<int>(j));
  return c;
}

// A hand-over: an object with a's robot (from a's onset, or set moving at its touch: an
// object's pieces pending with a's) went on while it rested.
bool Labeller::letGo(const Motion& a, const Motion& b) const {
  const auto& E = spec_.entities;
  if (E[a.entity].kind != task::EntityKind::Robot) return false;
  const double slack = options_.still_s / 2;  // the precision onsets and offsets are dated to
  for (int j = 0; j < static_cast<int>(E.size()); ++j) {
    if (E[j].kind != task::EntityKind::Object || !together(a.at_offset, a.entity, j) ||
        (b.at_onset[j] - a.at_offset[j]).norm() < options_.nudge_m)
      continue;
    // With it: at its onset already, or set moving at its touch while it moved.
    if (together(a.at_onset, a.entity, j)) return true;
    for (const Motion& l : pending_)
      if (l.entity == j && l.on_t >= a.on_t - slack && l.on_t <= a.off_t && together(l.at_onset, a.entity, j))
        return true;
  }
  return false;
}

// A robot (or the load it pushes) stopped short of a body, farther than a side touch reads
// (half the radius from contact), and went on to touch it (within that): the last of its
// approach. A hand's bump ends anywhere; an object's pieces go as its carrier's.
bool Labeller::closedIn(const Motion& a, const Motion& b, int body, int load) const {
  if (spec_.entities[a.entity].kind != task::EntityKind::Robot) return false;
  const int front = load >= 0 ? load : a.entity;
  const double contact = spec_.contactDistance(front, body);
  if (contact <= 0) return false;
  const double short_by = (a.at_offset[front] - a.at_offset[body]).norm() - contact;
  const double gap = (b.at_offset[front] - b.at_offset[body]).norm() - contact;
  return short_by > spec_.arrival_radius / 2 && std::abs(gap) <= spec_.arrival_radius / 2;
}

// An object that moved with no robot's motion, at one place with a resting robot all the way
// (swung round it as it turned in place, slower or shorter than a motion reads), whose next
// motion goes with that robot's: the start of that robot's carry. An object does not move
// alone.
bool Labeller::swungBeforeItsCarry(const Motion& a, const Motion& b) const {
  const auto& E = spec_.entities;
  if (E[a.entity].kind != task::EntityKind::Object) return false;
  const auto moving = [&](int r, const Motion& o) {
    return std::any_of(pending_.begin(), pending_.end(),
                       [&](const Motion& m) { return m.entity == r && m.on_t <= o.off_t && o.on_t <= m.off_t; });
  };
  for (int r = 0; r < static_cast<int>(E.size()); ++r) {
    if (E[r].kind != task::EntityKind::Robot) continue;
    if (moving(r, a) && a.max_distance[r] <= task::togetherDistance(spec_, a.entity, r)) return false;  // carried
  }
  // With it at both ends and in between (a resting body's distance is not measured on rows
  // the tracker repeats, so the ends decide).
  for (int r = 0; r < static_cast<int>(E.size()); ++r)
    if (E[r].kind == task::EntityKind::Robot && together(a.at_onset, a.entity, r) &&
        together(a.at_offset, a.entity, r) && a.max_distance[r] <= task::togetherDistance(spec_, a.entity, r) &&
        b.max_distance[r] <= task::togetherDistance(spec_, b.entity, r) && moving(r, b))
      return true;
  return false;
}

// A pause: a motion that stopped away from every entity, or over one but goes on in the
// heading it came in (not taking along what it stopped at), goes on within pause_s.
bool Labeller::pausedOnItsWay(const Motion& a, const Motion& b) const {
  // What moved with it went on without it: a hand-over, read from the contact that
  // changed, wherever the giver stopped and whichever way it leaves.
  if (letGo(a, b)) return false;
  if (swungBeforeItsCarry(a, b)) return true;
  // No rest between them (within the precision onsets and offsets are dated to), or b
  // crept on before a still_s of rest: one motion, slower than a rest reads, found in
  // pieces (cutAtContacts() cuts where what moves with it changes).
  const double rest = b.on_t - a.off_t;
  if (rest < options_.still_s / 2 || (b.crept && rest < options_.still_s)) return true;
  if (headsBack(a, b)) return true;
  // Went round an object it stood at (moving it less than a nudge: no carry of its own), to
  // the side it then pushes it from, maybe pushing a little before a pause: the push's
  // start, not a motion to the object.
  for (int j = 0; j < static_cast<int>(spec_.entities.size()); ++j)
    if (j != a.entity && spec_.entities[j].kind == task::EntityKind::Object && together(a.at_onset, a.entity, j) &&
        together(a.at_offset, a.entity, j) && (a.at_offset[j] - a.at_onset[j]).norm() < options_.nudge_m &&
        staysWith(b, j))
      return true;
  // What a carried (an object that stayed with it) ends a carrier's motion.
  int load = -1;
  for (int j = 0; j < static_cast<int>(spec_.entities.size()); ++j)
    if (j != a.entity && spec_.entities[j].kind == task::EntityKind::Object && staysWith(a, j) &&
        (load < 0 || a.max_distance[j] < a.max_distance[load]))
      load = j;
  const EndPoint ep =
      endPoint(spec_, a.entity, a.start, a.end, a.at_onset, candidatesOf(a), load, &a.at_offset, /*touching=*/true);
  // Stopped away from every entity; a piece shorter than a nudge only where it goes on in
  // its heading (a robot nudged by a hand or a body is no start of its next motion).
  const bool heading_kept = a.end_dir.dot(b.start_dir) >= std::cos(options_.heading_rad);
  if (ep.target < 0) return heading_kept || (a.end - a.start).norm() >= options_.nudge_m;
  if (!heading_kept) return false;
  if ((b.end - a.end).norm() < options_.nudge_m) return closedIn(a, b, ep.target, load);
  // Over an entity: goes on in the heading it came in, farther than a nudge.
  // Went to an object and moves on with it: a fetch, then a carry.
  for (int c : ep.tied)
    if (staysWith(b, c)) return false;
  return !staysWith(b, ep.target);
}

// Bumped by a hand and put back: a went a short way (less than twice a nudge) and b heads
// back to where a began.
bool Labeller::headsBack(const Motion& a, const Motion& b) const {
  const Vector2d back = a.start - a.end;
  return back.norm() > 0 && back.norm() < 2 * options_.nudge_m &&
         b.start_dir.dot(back.normalized()) > std::cos(options_.heading_rad);
}

bool Labeller::bumpedAndPutBack(const Motion& a, const Motion& b) const {
  return b.on_t - a.off_t <= options_.pause_s && headsBack(a, b) && (b.end - a.start).norm() < options_.nudge_m;
}

bool Labeller::together(const std::vector<Vector2d>& at, int a, int b) const {
  return task::together(spec_, a, at[a], b, at[b]);
}

namespace {

/// `m` up to (from) a cut at row `row`, time `t`, where every entity stood at `at`.
Motion before(const Motion& m, int row, double t, const std::vector<Vector2d>& at) {
  Motion a = m;
  a.off_row = std::max(row - 1, a.on_row);
  a.off_t = std::max(t, a.on_t);
  a.end = at[m.entity];
  a.at_offset = at;
  if ((a.end - a.start).norm() > 0) a.end_dir = (a.end - a.start).normalized();
  return a;
}
Motion after(const Motion& m, int row, double t, const std::vector<Vector2d>& at) {
  Motion b = m;
  b.on_row = row;
  b.on_t = t;
  b.start = at[m.entity];
  b.at_onset = at;
  b.resumed = false;
  b.rested_at = b.leg_start = b.start;
  if ((b.end - b.start).norm() > 0) b.start_dir = (b.end - b.start).normalized();
  return b;
}

}  // namespace

bool Labeller::stoppedAtOnItsWay(const Motion& m, int b, double& turn) const {
  const double r = spec_.arrival_radius, contact = spec_.contactDistance(m.entity, b);
  if (b == m.entity || contact <= 0 || m.closest_row[b] <= m.on_row || m.closest_row[b] >= m.off_row) return false;
  // Touching: within a quarter of the arrival radius of contact, either side (as endPoint
  // reads a touch; bodies on a table do not overlap further than the tracker's noise).
  const double least = m.min_distance[b];
  if (std::abs(least - contact) > r / 4) return false;
  if ((m.at_onset[b] - m.start).norm() - least <= r || (m.at_offset[b] - m.end).norm() - least <= r) return false;
  const double mean_speed = (m.end - m.start).norm() / std::max(m.off_t - m.on_t, 1e-9);
  if (m.closest_speed[b] > mean_speed / 4) return false;
  const Vector2d in = m.closest_at[b] - m.start, out = m.end - m.closest_at[b];
  turn = std::acos(std::clamp(in.normalized().dot(out.normalized()), -1.0, 1.0));
  return true;
}

void Labeller::cutAtContacts(std::vector<Motion>& ms) const {
  using task::EntityKind;
  const auto& E = spec_.entities;
  auto kind = [&](const Motion& m) { return E[m.entity].kind; };
  // 1. An object handed on: a robot that was with it stops while another that touches it
  // starts (within pause_s), the object going on: one piece of the object's motion each.
  for (bool cut = true; cut;) {
    cut = false;
    for (size_t o = 0; o < ms.size() && !cut; ++o) {
      if (kind(ms[o]) != EntityKind::Object) continue;
      for (size_t a = 0; a < ms.size() && !cut; ++a) {
        const Motion& giver = ms[a];
        if (kind(giver) != EntityKind::Robot || giver.off_row <= ms[o].on_row || giver.off_row >= ms[o].off_row ||
            !together(giver.at_offset, giver.entity, ms[o].entity))
          continue;
        for (size_t b = 0; b < ms.size() && !cut; ++b) {
          const Motion& taker = ms[b];
          if (kind(taker) != EntityKind::Robot || taker.entity == giver.entity || taker.on_row <= giver.on_row ||
              taker.on_row <= ms[o].on_row || taker.on_row >= ms[o].off_row ||
              taker.on_t > giver.off_t + options_.pause_s || !together(taker.at_onset, taker.entity, ms[o].entity))
            continue;
          const int row = taker.on_row;
          const double t = taker.on_t;
          Motion first = before(ms[o], row, t, taker.at_onset), second = after(ms[o], row, t, taker.at_onset);
          // Each piece went with its robot: as far apart as at its ends.
          first.max_distance[giver.entity] = std::max((first.at_onset[giver.entity] - first.start).norm(),
                                                      (first.at_offset[giver.entity] - first.end).norm());
          second.max_distance[taker.entity] = std::max((second.at_onset[taker.entity] - second.start).norm(),
                                                       (second.at_offset[taker.entity] - second.end).norm());
          ms[a].off_row = std::min(ms[a].off_row, row - 1);
          ms[o] = std::move(first);
          ms.insert(ms.begin() + static_cast<long>(o) + 1, std::move(second));
          cut = true;
        }
      }
    }
  }
  // 2. A robot that reached an object and went on with it without stopping: its approach,
  // then its push, cut at the object's onset.
  for (bool cut = true; cut;) {
    cut = false;
    for (size_t o = 0; o < ms.size() && !cut; ++o) {
      const Motion& load = ms[o];
      if (kind(load) != EntityKind::Object) continue;
      for (size_t r = 0; r < ms.size() && !cut; ++r) {
        const Motion& m = ms[r];
        const int R = m.entity;
        if (kind(m) != EntityKind::Robot || m.on_row >= load.on_row || m.off_row <= load.on_row) continue;
        // Touching it as it started, having come from elsewhere, and still with it when the
        // first of the two stopped.
        const auto& at_end = m.off_row <= load.off_row ? m.at_offset : load.at_offset;
        // Already at it when it set off (going round it to the side it pushes from): no
        // approach.
        if (!together(load.at_onset, R, load.entity) || !together(at_end, R, load.entity) ||
            together(m.at_onset, R, load.entity) || (load.at_onset[R] - m.start).norm() < options_.nudge_m ||
            (load.at_onset[R] - m.rested_at).norm() < options_.nudge_m)
          continue;
        Motion approach = before(m, load.on_row, load.on_t, load.at_onset);
        Motion push = after(m, load.on_row, load.on_t, load.at_onset);
        push.max_distance[load.entity] = load.max_distance[R];
        ms[r] = std::move(approach);
        ms.insert(ms.begin() + static_cast<long>(r) + 1, std::move(push));
        cut = true;
      }
    }
  }
  // 3. A robot that stopped at a body on its way, without a pause, and left it in another
  // heading (beyond heading_rad, as a pause that turns): a step to the body and one on, cut
  // where it was closest. Kept heading, it may have slowed past: listed in emit().
  for (bool cut = true; cut;) {
    cut = false;
    for (size_t i = 0; i < ms.size() && !cut; ++i) {
      const Motion& m = ms[i];
      if (kind(m) != EntityKind::Robot) continue;
      int at = -1;
      for (int b = 0; b < static_cast<int>(E.size()); ++b) {
        double turn = 0;
        if (!staysWith(m, b) && stoppedAtOnItsWay(m, b, turn) && turn > options_.heading_rad &&
            (at < 0 || m.closest_row[b] < m.closest_row[at]))
          at = b;
      }
      if (at < 0 || goesRoundItsLoad(m, m.closest_scene[at])) continue;
      const int row = m.closest_row[at];
      const double t = m.closest_t[at];
      const std::vector<Vector2d> scene = m.closest_scene[at];
      Motion stop = before(m, row + 1, t, scene), on = after(m, row + 1, t, scene);
      ms[i] = std::move(stop);
      ms.insert(ms.begin() + static_cast<long>(i) + 1, std::move(on));
      cut = true;
    }
  }
}

bool Labeller::goesRoundItsLoad(const Motion& m, const std::vector<Vector2d>& at) const {
  const auto& E = spec_.entities;
  for (int j = 0; j < static_cast<int>(E.size()); ++j)
    if (E[j].kind == task::EntityKind::Object && together(m.at_onset, m.entity, j) &&
        together(m.at_offset, m.entity, j) && together(at, m.entity, j) &&
        (m.at_offset[j] - m.at_onset[j]).norm() >= options_.nudge_m)
      return true;
  return false;
}

bool Labeller::startsAStep(double step_off_t, const Motion& m) const {
  // Onsets and offsets are dated to within about still_s / 2 (a few rows).
  return m.on_t >= step_off_t - options_.still_s / 2;
}

std::vector<Motion> Labeller::joinPauses() const {
  std::vector<Motion> ms = pending_;
  std::stable_sort(ms.begin(), ms.end(), [](const Motion& a, const Motion& b) {
    return a.entity != b.entity ? a.entity < b.entity : a.on_row < b.on_row;
  });
  std::vector<Motion> merged;
  // A motion back to where the entity rested (a nudge put back) is done: nothing joins it.
  auto putBack = [&](const Motion& a) { return (a.end - a.rested_at).norm() < options_.start_m; };
  for (size_t i = 0; i < ms.size(); ++i) {
    Motion& m = ms[i];
    // A hand's bump and its put-back, seen whole, are a nudge of their own: the bump is
    // no piece of the motion before it, even in its heading.
    const bool bump = i + 1 < ms.size() && ms[i + 1].entity == m.entity && bumpedAndPutBack(m, ms[i + 1]);
    if (!merged.empty() && merged.back().entity == m.entity && !bump) {
      Motion& a = merged.back();
      if (m.on_t - a.off_t <= options_.pause_s && !putBack(a) && pausedOnItsWay(a, m)) {
        a.continueWith(m);
        a.whole_off_row = m.off_row;
        a.whole_off_t = m.off_t;
        a.resumed = true;
        continue;
      }
    }
    merged.push_back(std::move(m));
  }
  return merged;
}

void Labeller::dropNudges(std::vector<Motion>& merged) const {
  auto movedAnObject = [&](const Motion& m) {
    return std::any_of(merged.begin(), merged.end(),
                       [&](const Motion& o) { return (o.end - o.start).norm() >= options_.nudge_m && sweptBy(o, m); });
  };
  std::vector<bool> nudge(merged.size());
  for (size_t i = 0; i < merged.size(); ++i)
    nudge[i] = (merged[i].end - merged[i].start).norm() < options_.nudge_m && !movedAnObject(merged[i]);
  for (size_t i = merged.size(); i-- > 0;)
    if (nudge[i]) merged.erase(merged.begin() + static_cast<long>(i));
}

void Labeller::dropHandedOver(std::vector<Motion>& merged) const {
  merged.erase(std::remove_if(merged.begin(), merged.end(), [&](const Motion& m) { return m.off_row <= handed_off_; }),
               merged.end());
  for (auto& m : merged) m.on_row = std::max(m.on_row, handed_off_ + 1);
}

std::vector<Labeller::Group> Labeller::groupSteps(std::vector<Motion> merged, std::vector<int>& group_off) const {
  std::stable_sort(merged.begin(), merged.end(), [](const Motion& a, const Motion& b) { return a.on_row < b.on_row; });
  std::vector<Group> groups;
  int max_off = -1;
  double max_off_t = 0;
  for (auto& m : merged) {
    if (groups.empty() || m.on_row > max_off || startsAStep(max_off_t, m)) {
      groups.emplace_back(), group_off.push_back(-1);
      max_off = -1;
    }
    max_off = std::max(max_off, m.off_row);
    max_off_t = groups.back().motions.empty() ? m.off_t : std::max(max_off_t, m.off_t);
    group_off.back() = max_off;
    // One token per entity and step: a second motion of the same entity joins its first.
    auto& g = groups.back().motions;
    auto same = std::find_if(g.begin(), g.end(), [&](const Motion& o) { return o.entity == m.entity; });
    if (same == g.end()) {
      g.push_back(std::move(m));
      continue;
    }
    groups.back().notes.push_back({m.on_row,
                                   spec_.entities[m.entity].name +
                                       " moved again in the same step (first motion ended at line " +
                                       std::to_string(same->off_row + 2) + "); taken as one motion, not two steps",
                                   m.entity});
    same->whole_off_row = std::max(same->whole_off_row, m.whole_off_row);
    same->whole_off_t = std::max(same->whole_off_t, m.whole_off_t);
    same->continueWith(m);
  }
  return groups;
}

size_t Labeller::finalGroups(const std::vector<Group>& groups, const std::vector<int>& group_off,
                             const std::vector<int>& last_on, const MotionSegmenter::Horizon& horizon) const {
  size_t final_groups = 0;
  for (; final_groups < groups.size(); ++final_groups) {
    bool final = group_off[final_groups] < horizon.row;
    for (const auto& m : groups[final_groups].motions)
      final = final && m.whole_off_row < horizon.row &&
              (horizon.t - m.whole_off_t > options_.pause_s || last_on[m.entity] > m.on_row);
    if (!final) break;
  }
  return final_groups;
}

void Labeller::decide(bool at_end) {
  next_check_t_ = std::numeric_limits<double>::infinity();
  if (pending_.empty()) return;
  // 1. Pauses: a motion and the next one of its entity, within pause_s, are one.
  std::vector<Motion> merged = joinPauses();
  // 2. Nudges: a motion, joined across its pauses, that ends where it began (less than
  // nudge_m away: bumped and put back) is no token, unless it moved an object farther (a
  // robot turning with its load: an object does not move alone).
  dropNudges(merged);
  cutAtContacts(merged);
  // Pieces of steps handed over already (a motion cut in two waits for its second piece).
  // A motion that began as the last one handed over ended (a push after a short stop at
  // the box: the one's onset and the other's offset are dated from the same rows at rest)
  // begins after it.
  dropHandedOver(merged);
  // The last motion of each entity may still be joined by a later one across a pause.
  std::vector<int> last_on(spec_.entities.size(), -1);
  for (const auto& m : merged) last_on[m.entity] = std::max(last_on[m.entity], m.on_row);
  // 3. Steps: motions that overlap in time; a step ends when every one of them has stopped.
  std::vector<int> group_off;  // [group] its last offset row
  std::vector<Group> groups = groupSteps(std::move(merged), group_off);
  // A group is final when no later motion can begin within it (the horizon is past its
  // end) nor join one of its motions across a pause (the horizon is pause_s past it, or
  // the entity has moved again since); groups are final in order.
  const MotionSegmenter::Horizon horizon = segmenter_.horizon();
  const size_t final_groups = at_end ? groups.size() : finalGroups(groups, group_off, last_on, horizon);
  if (final_groups > 0) {
    const int last_off = group_off[final_groups - 1];
    // A motion cut in two stays while its second piece is in a step not decided yet.
    pending_.erase(
        std::remove_if(pending_.begin(), pending_.end(), [&](const Motion& m) { return m.off_row <= last_off; }),
        pending_.end());
    handed_off_ = std::max(handed_off_, last_off);
    for (size_t k = 0; k < final_groups; ++k) handOver(std::move(groups[k]));
  }
  // Again when the horizon passes a time that can make a group final (a motion's end, or
  // pause_s after it); none ahead: when motions arrive (a running motion holds it back).
  for (const auto& m : pending_)
    for (const double when : {m.off_t, m.off_t + options_.pause_s})
      if (when >= horizon.t) next_check_t_ = std::min(next_check_t_, when);
}

namespace {

std::set<int> moversOf(const std::vector<Motion>& motions) {
  std::set<int> out;
  for (const auto& m : motions) out.insert(m.entity);
  return out;
}

}  // namespace

std::map<task::EntityKind, int> Labeller::kindsOf(const std::set<int>& entities) const {
  std::map<task::EntityKind, int> n;
  for (const int e : entities) ++n[spec_.entities[e].kind];
  return n;
}

std::string Labeller::kindsText(const std::map<task::EntityKind, int>& kinds) {
  std::string s;
  for (const auto& [kind, count] : kinds)
    s += (s.empty() ? "" : " and ") + std::to_string(count) + " " + task::toString(kind) + (count > 1 ? "s" : "");
  return s.empty() ? "nothing" : s;
}

std::set<int> Labeller::exampleMovers(size_t k) const {
  std::set<int> want;
  if (k < ex_motion_.size())
    for (const auto& t : ex_motion_[k]->tokens)
      if (t.isMotion()) want.insert(t.entity);
  return want;
}

bool Labeller::joinedItsBodies(const Group& g, const Group& first) const {
  const auto& E = spec_.entities;
  for (const Motion& m : g.motions) {
    bool joined = false;
    for (const Motion& o : first.motions)
      joined = joined || (E[o.entity].kind != task::EntityKind::Goal && together(m.at_offset, m.entity, o.entity));
    if (!joined) return false;
  }
  return true;
}

void Labeller::handOver(Group g) {
  if (partial_) {
    // Robots of one step started apart, the first done before the next began: one step
    // when the example's step has their movers, or as many of each kind (its scene may
    // have chosen other robots) and the second began within pause_s of the first's end
    // (a person's pause, as between the pieces of one motion).
    std::set<int> both = moversOf(partial_->motions);
    bool disjoint = true;
    for (const int e : moversOf(g.motions)) disjoint = both.insert(e).second && disjoint;
    double first_on = g.motions.front().on_t, partial_off = 0;
    for (const auto& m : g.motions) first_on = std::min(first_on, m.on_t);
    for (const auto& m : partial_->motions) partial_off = std::max(partial_off, m.off_t);
    const std::set<int> want = exampleMovers(groups_seen_);
    Group first = std::move(*partial_);
    partial_.reset();
    if (disjoint && (both == want || ((first_on - partial_off < options_.pause_s || joinedItsBodies(g, first)) &&
                                      kindsOf(both) == kindsOf(want)))) {
      for (auto& m : g.motions) first.motions.push_back(std::move(m));
      for (auto& n : g.notes) first.notes.push_back(std::move(n));
      g = std::move(first);
    } else {
      place(std::move(first));
    }
  }
  // Fewer movers of each kind than the example's step: the rest of it may follow.
  const std::set<int> movers = moversOf(g.motions), want = exampleMovers(groups_seen_);
  if (example_ && movers != want && movers.size() < want.size()) {
    const auto have = kindsOf(movers), need = kindsOf(want);
    bool part = true;
    for (const auto& [kind, count] : have) part = part && need.count(kind) && need.at(kind) >= count;
    if (part) {
      partial_ = std::move(g);
      return;
    }
  }
  place(std::move(g));
}

void Labeller::place(Group g) {
  ++groups_seen_;
  if (alignment_ != Alignment::Open) return emit(g, alignment_ == Alignment::Aligned);
  // With an example: aligned when its motion steps have the example's moving entities,
  // step by step, and as many steps (known at the end; a step too many settles it now).
  const size_t k = held_.size();
  const bool fits = k < ex_motion_.size() && moversOf(g.motions) == exampleMovers(k);
  held_.push_back(std::move(g));
  if (!fits) settle(false);
}

void Labeller::settle(bool aligned) {
  alignment_ = aligned ? Alignment::Aligned : Alignment::NotAligned;
  if (!aligned && ex_has_inplace_)
    note(0, "the example's in-place actions are not placed: this demonstration's motion has other steps than " +
                example_->source + "'s");
  for (auto& g : held_) emit(g, aligned);
  held_.clear();
}

// Action words: the example's, then task.yaml's action_rules (the first that matches),
// else the task's first action (said when an example or rules were there to ask).
const task::ActionRule* Labeller::rule(int mover, int target, int load) const {
  for (const auto& r : spec_.action_rules)
    if (r.matches(spec_.entities[mover], spec_.entities[target], load)) return &r;
  return nullptr;
}

std::string Labeller::word(int mover, int target, int load, int row) {
  if (example_) {
    for (const auto& k : {kindKey(spec_, mover, target, load), coarseKindKey(spec_, mover, target, load)}) {
      auto it = example_->words.find(k);
      if (it != example_->words.end()) return it->second;
    }
  }
  if (const task::ActionRule* r = rule(mover, target, load)) return r->action;
  if (example_ || !spec_.action_rules.empty()) {
    std::string where;
    if (example_) where = "in the example " + example_->source;
    if (!spec_.action_rules.empty()) where += std::string(example_ ? " nor " : "") + "in task.yaml's action_rules";
    note(
        row,
        "no motion of the kind " + kindKey(spec_, mover, target, load) + " " + where + "; took the task's first action",
        mover);
  }
  return spec_.actions.empty() ? "move" : spec_.actions.front();
}

// In-place-only steps of the example, spread over the rows between two motion steps.
void Labeller::placeInPlace(const std::vector<const task::Step*>& steps, int from, int to) {
  const int count = static_cast<int>(steps.size());
  if (count == 0) return;
  const int span = to - from + 1;
  if (span < 2 * count + 1) {
    note(std::max(from, 0), "no still time to place the example's in-place step(s) here");
    return;
  }
  for (int j = 0; j < count; ++j) {
    InferredStep st;
    st.keyframe_row = from + span * (2 * j + 1) / (2 * count + 1);
    const int last = from + span * (2 * j + 2) / (2 * count + 1) - 1;
    for (const auto& t : steps[j]->tokens) {
      InferredToken it;
      it.token = t;
      it.first_row = it.onset_row = st.keyframe_row;
      it.last_row = std::max(last, st.keyframe_row);
      it.in_place = true;
      it.kind = "in-place";
      st.tokens.push_back(it);
    }
    out_.steps.push_back(std::move(st));
  }
}

void Labeller::noteStepsDiffer(size_t k, const std::vector<Motion>& g, int row) {
  // A step whose movers are not the example's kinds (robots of one step started apart, two
  // steps run together, a motion lost or added): it and every step after it may be
  // numbered wrong, so all their tokens are listed, under one note.
  if (!example_ || steps_differ_ || kindsOf(moversOf(g)) == kindsOf(exampleMovers(k))) return;
  steps_differ_ = true;
  steps_differ_note_ = "step " + std::to_string(k + 1) + " moves " + kindsText(kindsOf(moversOf(g))) +
                       " where the example's step " + std::to_string(k + 1) + " moves " +
                       kindsText(kindsOf(exampleMovers(k))) +
                       " (robots of one step started apart, two steps run together, or a motion missed?): "
                       "this step and the ones after it are listed";
  note(row, steps_differ_note_);
}

std::vector<int> Labeller::carriersOf(const std::vector<Motion>& g) const {
  const auto& E = spec_.entities;
  std::vector<int> carrier(g.size(), -1);
  for (size_t i = 0; i < g.size(); ++i) {
    if (E[g[i].entity].kind != task::EntityKind::Object) continue;
    double best = 1e9;
    for (size_t j = 0; j < g.size(); ++j) {
      const int rb = g[j].entity;
      if (j == i || !sweptBy(g[i], g[j])) continue;
      if (g[i].max_distance[rb] < best) best = g[i].max_distance[rb], carrier[i] = static_cast<int>(j);
    }
  }
  return carrier;
}

void Labeller::resolveTie(InferredToken& tok, const Motion& m, const EndPoint& ep, size_t k, bool aligned) {
  const auto& E = spec_.entities;
  std::vector<int> all = ep.tied;
  all.push_back(ep.target);
  tok.tied = all;
  if (aligned) {
    int want = -1;
    for (const auto& t : ex_motion_[k]->tokens)
      if (t.entity == m.entity) {
        want = t.target;
        break;
      }
    if (std::find(all.begin(), all.end(), want) != all.end()) {
      tok.token.target = want;
      return;
    }
  }
  if (example_) {
    // The example's choice between the same kinds, else between a goal and the bodies
    // on it (the goal, or the body touched).
    for (const bool bodies : {false, true}) {
      auto it = example_->tie_kind.find(tiedKinds(spec_, all, bodies));
      int found = -1, count = 0, exact = -1, exact_count = 0;
      if (it != example_->tie_kind.end())
        for (int c : all)
          if (kindClass(E[c].kind, bodies) == kindClass(it->second, bodies)) {
            found = c, ++count;
            if (E[c].kind == it->second) exact = c, ++exact_count;
          }
      // Several bodies touched at an occupied goal: the one of the kind the example took.
      if (count > 1 && exact_count == 1) found = exact, count = 1;
      if (count == 1) {
        tok.token.target = found;
        // A body of another kind than the one the example took: listed.
        if (E[found].kind != it->second)
          note(m.off_row,
               E[m.entity].name + " ended between " + namesOf(spec_, all) + "; took " + E[found].name +
                   " as the example took a " + task::toString(it->second) + " there, not the goal",
               m.entity);
        return;
      }
    }
    // Else the one end the example has a motion of that kind to (a robot sent to a
    // robot, never to a goal, in the example).
    int found = -1, count = 0;
    for (int c : all)
      if (example_->words.count(kindKey(spec_, m.entity, c, tok.load))) found = c, ++count;
    if (count == 1) {
      tok.token.target = found;
      return;
    }
  }
  note(m.off_row,
       E[m.entity].name + " ended between " + namesOf(spec_, all) + " (the same distance within " +
           metres(spec_.arrival_radius / 2) + " m); took " + E[ep.target].name,
       m.entity);
}

// Stopped within the arrival radius (the task's precision of an end point) of touching a
// body ahead of it (within a right angle of its heading): a person stopping short of the
// body it drove to, not one stopping on its way past it.
bool Labeller::stoppedShortFacing(const Motion& m, int body) const {
  const double contact = spec_.contactDistance(m.entity, body);
  const Vector2d to = m.at_offset[body] - m.end;
  return contact > 0 && to.norm() - contact <= spec_.arrival_radius && m.end_dir.dot(to.normalized()) > 0;
}

bool Labeller::behindARow(const Motion& m, int target, const std::vector<Motion>& step) const {
  const double from_target = (m.end - m.at_offset[target]).norm();
  for (const Motion& o : step)
    if (o.entity != m.entity && o.entity != target && stoppedShortFacing(m, o.entity) &&
        (m.at_offset[o.entity] - m.at_offset[target]).norm() < from_target)
      return true;
  return false;
}

void Labeller::readTarget(InferredToken& tok, const Motion& m, int load, size_t k, bool aligned,
                          const std::vector<Motion>& step, const std::vector<Vector2d>& step_end) {
  const auto& E = spec_.entities;
  EndPoint ep = endPoint(spec_, m.entity, m.leg_start, m.end, m.at_onset, candidatesOf(m), load, &m.at_offset);
  if (ep.target < 0) {
    // It stopped short and the rest of its step came in front of it (a robot leaving room
    // for those still on their way to the same body): the crowd round the target as the
    // step left it.
    const EndPoint later = endPoint(spec_, m.entity, m.leg_start, m.end, m.at_onset, candidatesOf(m), load, &step_end);
    if (later.target >= 0) ep = later;
  }
  tok.token.target = ep.target;
  if (ep.target < 0) {
    tok.token.target = ep.nearest;
    if (ep.nearest >= 0 && !stoppedShortFacing(m, ep.nearest) && !behindARow(m, ep.nearest, step))
      note(m.off_row,
           E[m.entity].name + " stopped halfway: " + metres(ep.nearest_m) + " m from " + E[ep.nearest].name +
               ", the nearest entity, taken as its target; or it went on later to another",
           m.entity);
  } else if (!ep.tied.empty()) {
    resolveTie(tok, m, ep, k, aligned);
  }
}

bool Labeller::nameAction(InferredToken& tok, const Motion& m, bool is_load) {
  const auto& E = spec_.entities;
  tok.kind = kindKey(spec_, m.entity, tok.token.target, tok.load);
  // An object moving alone is reported unless the example shows such a motion or a
  // rule of task.yaml names the word of an object's motion there.
  const task::ActionRule* object_rule = rule(m.entity, tok.token.target, tok.load);
  const bool object_rule_stated = object_rule && object_rule->mover_kind == task::EntityKind::Object;
  const bool alone = E[m.entity].kind == task::EntityKind::Object && !is_load &&
                     !(example_ && example_->words.count(tok.kind)) && !object_rule_stated;
  if (alone)
    note(m.on_row,
         "object " + E[m.entity].name + " moved alone (no robot with it) to " + E[tok.token.target].name +
             "; or a robot carried it",
         m.entity);
  tok.token.action = word(m.entity, tok.token.target, tok.load, m.on_row);
  return alone;
}

void Labeller::readChain(std::vector<InferredToken>& tokens, const std::vector<Motion>& g,
                         const std::vector<int>& carrier) {
  const auto& E = spec_.entities;
  for (size_t i = 0; i < g.size(); ++i) {
    InferredToken& tok = tokens[i];
    if (carrier[i] >= 0 || tok.load != 0 || tok.token.target < 0) continue;
    const int c = tok.token.target;
    // c moved in this step, by itself, to a body other than this one, and was there when this
    // motion ended (it had got there first: a crowd round that body, not a robot that left
    // later).
    int beyond = -1;
    for (size_t j = 0; j < g.size(); ++j)
      if (j != i && g[j].entity == c && carrier[j] < 0 && tokens[j].load == 0 && tokens[j].token.target >= 0 &&
          tokens[j].token.target != g[i].entity && spec_.footprint(tokens[j].token.target).obstacle &&
          g[j].off_t <= g[i].off_t + options_.still_s / 2)
        beyond = tokens[j].token.target;
    if (beyond < 0) continue;
    if (example_ && !example_->sends_to_movers) {
      tok.token.target = beyond;
      continue;
    }
    note(g[i].off_row,
         E[g[i].entity].name + " ended at " + E[c].name + ", which itself went to " + E[beyond].name +
             " in this step: sent to " + E[c].name + ", or to " + E[beyond].name +
             " (stopped at the crowd round it)?; took " + E[c].name,
         g[i].entity);
  }
}

std::vector<InferredToken> Labeller::motionTokens(const std::vector<Motion>& g, const std::vector<int>& carrier,
                                                  int first_row, size_t k, bool aligned) {
  std::vector<InferredToken> tokens(g.size());
  for (size_t i = 0; i < g.size(); ++i) {
    InferredToken& tok = tokens[i];
    tok.token.entity = g[i].entity;
    tok.first_row = first_row;
    tok.onset_row = g[i].on_row;
    tok.last_row = g[i].off_row;
    const bool has_load = std::find(carrier.begin(), carrier.end(), static_cast<int>(i)) != carrier.end();
    tok.load = carrier[i] >= 0 ? 2 : has_load ? 1 : 0;
  }
  // Carriers and lone movers first (every target, then chains through movers of the step,
  // then words), then their loads.
  const auto last =
      std::max_element(g.begin(), g.end(), [](const Motion& a, const Motion& b) { return a.off_row < b.off_row; });
  for (size_t i = 0; i < g.size(); ++i) {
    if (carrier[i] >= 0) continue;
    int load = -1;
    for (size_t j = 0; j < g.size() && load < 0; ++j)
      if (carrier[j] == static_cast<int>(i)) load = g[j].entity;
    readTarget(tokens[i], g[i], load, k, aligned, g, last->at_offset);
  }
  readChain(tokens, g, carrier);
  for (int pass = 0; pass < 2; ++pass)
    for (size_t i = 0; i < g.size(); ++i) {
      const bool is_load = carrier[i] >= 0;
      if (is_load != (pass == 1)) continue;
      InferredToken& tok = tokens[i];
      if (is_load) {
        tok.carrier = g[carrier[i]].entity;
        tok.token.target = tokens[carrier[i]].token.target;
      }
      if (tok.token.target < 0 || !nameAction(tok, g[i], is_load)) continue;
      // The robots of the step it ended with are the ones that may have carried it.
      for (size_t j = 0; j < g.size(); ++j)
        if (j != i && spec_.entities[g[j].entity].kind == task::EntityKind::Robot &&
            together(g[i].at_offset, g[j].entity, g[i].entity))
          note(g[j].off_row,
               spec_.entities[g[j].entity].name + " ended with object " + spec_.entities[g[i].entity].name +
                   ", which moved alone: did " + spec_.entities[g[j].entity].name + " carry it?",
               g[j].entity);
    }
  return tokens;
}

void Labeller::noteStopsOnTheWay(const std::vector<Motion>& g, const std::vector<int>& carrier,
                                 const std::vector<InferredToken>& tokens) {
  // What the motion leaves open: a body it came to on its way, nearly stopping there, and
  // left in the heading it came in (a turn there is cut): a slow pass, or a stop without a
  // pause (two steps)?
  const auto& E = spec_.entities;
  for (size_t i = 0; i < g.size(); ++i) {
    const Motion& m = g[i];
    const InferredToken& tok = tokens[i];
    if (tok.token.target < 0 || carrier[i] >= 0) continue;
    for (int b = 0; b < static_cast<int>(E.size()); ++b) {
      const bool load = std::any_of(tokens.begin(), tokens.end(), [&](const InferredToken& t) {
        return t.token.entity == b && t.carrier == m.entity;
      });
      double turn = 0;
      if (b == tok.token.target || load || !stoppedAtOnItsWay(m, b, turn) || goesRoundItsLoad(m, m.closest_scene[b]))
        continue;
      // A step to b would be a motion of a kind the example never makes: a slow pass.
      if (example_ && !example_->words.count(kindKey(spec_, m.entity, b, tok.load)) &&
          !example_->words.count(coarseKindKey(spec_, m.entity, b, tok.load)))
        continue;
      note(m.off_row,
           E[m.entity].name + " nearly stopped at " + E[b].name + " on its way to " + E[tok.token.target].name +
               ", keeping its heading: one motion, or a step to " + E[b].name + " and another on; taken as one",
           m.entity);
    }
  }
}

void Labeller::markUnsure(std::vector<InferredToken>& tokens, size_t notes_from) const {
  // A token some note of this step doubts is listed to check.
  const auto list = [](InferredToken& t, const std::string& why) {
    if (!t.unsure) t.doubt = why;
    t.unsure = true;
  };
  for (size_t i = notes_from; i < out_.notes.size(); ++i)
    for (auto& t : tokens)
      if (!t.in_place && t.token.entity == out_.notes[i].entity) list(t, out_.notes[i].message);
  for (auto& t : tokens)
    if (steps_differ_) list(t, steps_differ_note_);
  for (auto& t : tokens)  // a load goes where its carrier went
    for (const auto& c : tokens)
      if (t.carrier >= 0 && c.token.entity == t.carrier && c.unsure) list(t, c.doubt);
}

void Labeller::noteArrivedAgain(const std::vector<Motion>& g, const std::vector<InferredToken>& tokens) {
  const auto& E = spec_.entities;
  for (size_t i = 0; i < g.size(); ++i) {
    const InferredToken& t = tokens[i];
    if (t.token.target < 0 || t.carrier >= 0) continue;
    LastArrival& last = last_arrival_[t.token.entity];
    if (last.target == t.token.target && (g[i].at_offset[t.token.target] - last.target_at).norm() < options_.nudge_m)
      note(g[i].on_row,
           E[t.token.entity].name + " moved to " + E[t.token.target].name +
               " again, where its last motion ended (line " + std::to_string(last.row + 2) +
               "): a bump put back, or the rest of that motion?",
           t.token.entity);
    last = {t.token.target, g[i].at_offset[t.token.target], g[i].off_row};
  }
}

void Labeller::emit(Group& group, bool aligned) {
  const size_t k = emitted_groups_++;
  const size_t notes_from = out_.notes.size();
  const auto& g = group.motions;

  InferredStep step;
  step.keyframe_row = g.front().on_row;
  int step_off = 0;
  for (const auto& m : g)
    step.keyframe_row = std::min(step.keyframe_row, m.on_row), step_off = std::max(step_off, m.off_row);
  noteStepsDiffer(k, g, step.keyframe_row);
  // An entity that moved twice in one step (taken as one motion): doubtful where two steps
  // may have run together; not when this step and every one before it have the example's
  // kinds and numbers of movers.
  if (!example_ || steps_differ_)
    for (auto& nt : group.notes) out_.notes.push_back(std::move(nt));
  if (aligned) placeInPlace(ex_inplace_before_[k], prev_off_ + 1, step.keyframe_row - 1);

  // Loads (an object that stayed with a moving robot of the step all the way), then targets.
  const std::vector<int> carrier = carriersOf(g);
  std::vector<InferredToken> tokens = motionTokens(g, carrier, step.keyframe_row, k, aligned);
  noteStopsOnTheWay(g, carrier, tokens);
  noteArrivedAgain(g, tokens);
  // In-place actions of the aligned example step, for the entities that did not move.
  if (aligned)
    for (const auto& t : ex_motion_[k]->tokens)
      if (!t.isMotion()) {
        InferredToken it;
        it.token = t;
        it.first_row = it.onset_row = step.keyframe_row;
        it.last_row = step_off;
        it.in_place = true;
        it.kind = "in-place";
        tokens.push_back(it);
      }
  markUnsure(tokens, notes_from);
  for (auto& t : tokens)
    if (t.token.target >= 0 || t.in_place) step.tokens.push_back(std::move(t));
  std::sort(step.tokens.begin(), step.tokens.end(),
            [](const InferredToken& a, const InferredToken& b) { return a.token.entity < b.token.entity; });
  if (!step.tokens.empty()) out_.steps.push_back(std::move(step));
  prev_off_ = step_off;
}

Inference inferLabels(const task::Demonstration& d, const task::TaskSpec& spec, const Example* example) {
  Labeller l(spec, example);
  for (size_t i = 0; i < d.rows(); ++i) l.row(d.t[i], d.positions[i]);
  return l.finish();
}

namespace {

/// The label a person gave most rows of a motion (their labels and the motion's onset and
/// offset need not agree to the row: a robot braking after its label ended), or null.
const task::Label* labelOfMotion(const task::Demonstration& d, const InferredToken& t) {
  std::map<std::pair<std::string, int>, int> rows;
  const task::Label* most = nullptr;
  int most_rows = 0;
  for (int row = t.onset_row; row <= t.last_row; ++row) {
    const task::Label& l = d.labels[row][t.token.entity];
    if (l.isNull() || l.target < 0) continue;
    const int n = ++rows[{l.action, l.target}];
    if (n > most_rows) most = &l, most_rows = n;
  }
  return most;
}

}  // namespace

Example Example::fromDemonstration(const task::Demonstration& d, const task::TaskSpec& spec) {
  Example ex;
  ex.source = d.source;
  ex.steps = d.steps;
  const Inference inf = inferLabels(d, spec, nullptr);
  std::map<std::string, std::map<std::string, int>> votes;
  for (const auto& step : inf.steps)
    for (const auto& t : step.tokens) {
      const task::Label* most = labelOfMotion(d, t);
      if (!most) continue;
      const task::Label& l = *most;
      // The word of a kind of motion: as labelled; the kind: as the motion shows it.
      ++votes[kindKey(spec, t.token.entity, l.target, t.load)][l.action];
      ++votes[coarseKindKey(spec, t.token.entity, l.target, t.load)][l.action];
      if (!t.tied.empty() && std::find(t.tied.begin(), t.tied.end(), l.target) != t.tied.end())
        for (const bool bodies : {false, true})
          ex.tie_kind[tiedKinds(spec, t.tied, bodies)] = spec.entities[l.target].kind;
    }
  for (const auto& step : d.steps)
    for (const auto& t : step.tokens)
      for (const auto& o : step.tokens)
        ex.sends_to_movers =
            ex.sends_to_movers || (t.isMotion() && o.isMotion() && o.entity != t.entity && t.target == o.entity);
  for (const auto& [k, words] : votes) {
    auto best =
        std::max_element(words.begin(), words.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    ex.words[k] = best->first;
  }
  if (ex.words.empty())
    throw Error(Diagnostic{d.source, 0, 0,
                           "the example has no labelled motion to take action words from (label its motions, "
                           "or leave --example out)"});
  return ex;
}

LabelCursor::LabelCursor(const Inference& inference, size_t entities) : labels_(entities) {
  for (const auto& s : inference.steps)
    for (const auto& t : s.tokens)
      spans_.push_back({t.first_row, t.last_row, t.token.entity, {t.token.action, t.token.target}});
  std::stable_sort(spans_.begin(), spans_.end(), [](const Span& a, const Span& b) { return a.first < b.first; });
  next_ = [this](Span& s) {
    if (index_ == spans_.size()) return false;
    s = spans_[index_++];
    return true;
  };
}

LabelCursor::LabelCursor(std::function<bool(Span&)> next, size_t entities)
    : next_(std::move(next)), labels_(entities) {}

bool LabelCursor::peek() {
  if (ahead_) return true;
  Span s;
  if (!next_(s)) return false;
  if (s.first < last_first_)
    throw Error("label spans out of order: one begins at row " + std::to_string(s.first) + " after one at row " +
                std::to_string(last_first_) + " (a bug in ddace label)");
  if (s.entity < 0 || static_cast<size_t>(s.entity) >= labels_.size())
    throw Error("label span of entity " + std::to_string(s.entity) + ", the task has " +
                std::to_string(labels_.size()) + " (a bug in ddace label)");
  last_first_ = s.first;
  ahead_ = std::move(s);
  return true;
}

const std::vector<task::Label>& LabelCursor::at(int row) {
  open_.erase(std::remove_if(open_.begin(), open_.end(), [&](const Span& s) { return s.last < row; }), open_.end());
  while (peek() && ahead_->first <= row) {
    open_.push_back(std::move(*ahead_));
    ahead_.reset();
  }
  std::fill(labels_.begin(), labels_.end(), task::Label{});
  for (const auto& s : open_)
    if (s.first <= row) labels_[s.entity] = s.label;
  return labels_;
}

bool LabelCursor::exhausted() {
  return !peek();
}

void applyLabels(task::Demonstration& d, const Inference& inference) {
  LabelCursor cursor(inference, d.entities());
  d.has_label_columns.assign(d.entities(), false);
  for (const auto& s : inference.steps)
    for (const auto& t : s.tokens) d.has_label_columns[t.token.entity] = true;
  d.labels.resize(d.rows());
  for (size_t i = 0; i < d.rows(); ++i) d.labels[i] = cursor.at(static_cast<int>(i));
  d.analyze();
}

bool unlabelled(const task::Demonstration& d) {
  for (const auto& row : d.labels)
    for (const auto& l : row)
      if (!l.isNull()) return false;
  return true;
}

}  // namespace ddace::label
