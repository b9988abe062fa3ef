#include "ddace/exec/carried_objects.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "ddace/common/error.h"

namespace ddace::exec {

namespace {

std::string metres(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f cm", m * 100);
  return buf;
}

std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f s", s);
  return buf;
}

bool ended(SegmentState s) {
  return s == SegmentState::Done || s == SegmentState::Failed || s == SegmentState::Aborted;
}

}  // namespace

void CarriedObjectParams::validate() const {
  if (!(arrival_radius_m > 0)) throw Error("carried objects: arrival_radius_m must be > 0");
  if (!(arrival_tolerance_m >= 0)) throw Error("carried objects: arrival_tolerance_m must be >= 0");
  if (!(settle_s >= 0)) throw Error("carried objects: settle_s must be >= 0");
  if (!(pairing_s >= 0)) throw Error("carried objects: pairing_s must be >= 0");
}

std::optional<std::string> uncarriedObjectMotion(const task::TaskDir& dir) {
  for (size_t d = 0; d < dir.demos.size(); ++d)
    for (size_t s = 0; s < dir.demos[d].steps.size(); ++s) {
      const std::vector<task::Token>& step = dir.demos[d].steps[s].tokens;
      for (size_t i = 0; i < step.size(); ++i) {
        const task::Token& t = step[i];
        if (!t.isMotion() || dir.spec.entities.at(static_cast<size_t>(t.entity)).kind != task::EntityKind::Object)
          continue;
        bool carried = false;
        for (size_t k = 0; k < step.size() && !carried; ++k)
          carried = task::carriedLoad(dir.spec, step, k) == static_cast<int>(i);
        if (!carried)
          return "task '" + dir.spec.name + "': " + task::tokenKey(t, dir.spec) + " (demonstration " +
                 std::to_string(d + 1) + ", step " + std::to_string(s + 1) +
                 ") moves an object with no robot carrying it in its step; on the real table nothing moves it (run "
                 "it on mock robots: execute_sim.launch)";
      }
    }
  return std::nullopt;
}

CarriedObjects::CarriedObjects(task::TaskSpec spec, CarriedObjectParams params)
    : spec_(std::move(spec)), params_(params) {
  params_.validate();
  positions_.assign(spec_.entities.size(), Eigen::Vector2d::Zero());
  tracked_.assign(spec_.entities.size(), false);
}

void CarriedObjects::onRobotSegment(int robot, uint32_t segment_id, int step, const task::Token& token) {
  robots_[robot] = {segment_id, step, token};
  for (auto& [object, r] : objects_)
    if (r.carrier == robot) r.carrier = -1;  // replaced before it ended: it carries nothing now
  for (auto& entry : objects_) pair(entry.second);
}

std::vector<ObjectStatus> CarriedObjects::onRobotStatus(int robot, uint32_t segment_id, SegmentState state,
                                                        double now_s) {
  std::vector<ObjectStatus> out;
  const auto seg = robots_.find(robot);
  if (seg == robots_.end() || seg->second.segment_id != segment_id || !ended(state)) return out;
  for (auto it = objects_.begin(); it != objects_.end();) {
    Running& r = it->second;
    if (r.carrier != robot) {
      ++it;
      continue;
    }
    if (state == SegmentState::Done) {
      if (r.carrier_done_s < 0) r.carrier_done_s = now_s;
      ++it;
      continue;
    }
    out.push_back(status(it->first, r, state == SegmentState::Failed ? SegmentState::Failed : SegmentState::Aborted,
                         name(it->first) + ": its carrier " + name(robot) + "'s segment " +
                             (state == SegmentState::Failed ? "failed" : "was aborted") + " before it was delivered"));
    it = objects_.erase(it);
  }
  return out;
}

std::vector<ObjectStatus> CarriedObjects::onObjectSegment(int object, uint32_t segment_id, int step,
                                                          const task::Token& token, const Eigen::Vector2d& goal,
                                                          double now_s) {
  objects_.erase(object);
  Running r;
  r.segment_id = segment_id, r.step = step, r.token = token, r.goal = goal, r.since_s = now_s;
  if (token.entity != object || !token.isMotion())
    return {
        status(object, r, SegmentState::Failed,
               "segment " + std::to_string(segment_id) + " for " + name(object) + " does not move " + name(object))};
  r.start_distance_m = distance(object, r);
  pair(r);
  objects_[object] = r;
  return {status(object, r, SegmentState::Accepted, "")};
}

std::vector<ObjectStatus> CarriedObjects::stopObject(int object) {
  const auto it = objects_.find(object);
  if (it == objects_.end()) return {};
  const ObjectStatus s = status(object, it->second, SegmentState::Aborted, name(object) + ": segment cancelled");
  objects_.erase(it);
  return {s};
}

void CarriedObjects::onPositions(const std::vector<Eigen::Vector2d>& positions, const std::vector<bool>& tracked) {
  if (positions.size() != positions_.size() || tracked.size() != tracked_.size())
    throw Error("carried objects: " + std::to_string(positions.size()) + " positions for the " +
                std::to_string(positions_.size()) + " entities of task '" + spec_.name + "'");
  positions_ = positions;
  tracked_ = tracked;
}

std::vector<ObjectStatus> CarriedObjects::update(double now_s) {
  std::vector<ObjectStatus> out;
  const double within = params_.arrival_radius_m + params_.arrival_tolerance_m;
  for (auto it = objects_.begin(); it != objects_.end();) {
    const int object = it->first;
    Running& r = it->second;
    const bool seen = tracked_[static_cast<size_t>(object)];
    const double d = distance(object, r);
    std::optional<ObjectStatus> s;
    if (r.carrier < 0) {
      if (now_s - r.since_s > params_.pairing_s)
        s = status(object, r, SegmentState::Failed,
                   task::tokenKey(r.token, spec_) + " (step " + std::to_string(r.step + 1) +
                       "): no robot carries it in its step, and nothing else moves " + name(object) + " on this table");
    } else if (r.carrier_done_s >= 0) {
      if (seen && d <= within) s = status(object, r, SegmentState::Done, "");
      else if (now_s - r.carrier_done_s > params_.settle_s)
        s = status(object, r, SegmentState::Failed,
                   name(object) + (seen ? " is " + metres(d) + " from its end point" : " is not seen by the tracker") +
                       " " + seconds(params_.settle_s) + " after its carrier " + name(r.carrier) +
                       " was done (within " + metres(within) + " needed)");
    }
    if (s) {
      out.push_back(*s);
      it = objects_.erase(it);
    } else {
      ++it;
    }
  }
  return out;
}

int CarriedObjects::carrierOf(int object) const {
  const auto it = objects_.find(object);
  return it == objects_.end() ? -1 : it->second.carrier;
}

void CarriedObjects::pair(Running& r) {
  if (r.carrier >= 0) return;
  for (const auto& [robot, seg] : robots_)
    if (carries(spec_, seg.step, seg.token, r.step, r.token)) {
      r.carrier = robot;
      return;
    }
}

ObjectStatus CarriedObjects::status(int object, const Running& r, SegmentState state,
                                    const std::string& message) const {
  ObjectStatus s;
  s.entity = object;
  s.segment_id = r.segment_id;
  s.state = state;
  s.distance_to_goal_m = distance(object, r);
  s.progress = state == SegmentState::Done ? 1.0
               : r.start_distance_m > 0    ? std::clamp(1.0 - s.distance_to_goal_m / r.start_distance_m, 0.0, 1.0)
                                           : 0.0;
  s.message = message;
  return s;
}

double CarriedObjects::distance(int object, const Running& r) const {
  return (positions_[static_cast<size_t>(object)] - r.goal).norm();
}

}  // namespace ddace::exec
