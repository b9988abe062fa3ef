#include "ddace/exec/follower_view.h"

#include <algorithm>
#include <cmath>

#include "ddace/task/body_geometry.h"

namespace ddace::exec {

FollowerView::FollowerView(std::map<std::string, task::Entity> kinds, double arrival_radius_m, double reach_m)
    : kinds_(std::move(kinds)), arrival_m_(arrival_radius_m), reach_m_(reach_m) {}

void FollowerView::track(const std::string& name, std::optional<task::EntityKind> kind, const Eigen::Vector2d& position,
                         bool stale, double seen_s) {
  task::Entity e{name, kind.value_or(task::EntityKind::Object), ""};  // unknown kind: keep off it
  if (auto known = kinds_.find(name); known != kinds_.end()) e = known->second;
  const BodyShape shape = bodyShape(e);
  if (!shape.obstacle) return;
  Tracked& t = bodies_[name];
  t.body.name = name;
  t.body.radius_m = shape.radius_m;
  t.body.robot = e.kind == task::EntityKind::Robot;
  const bool finite = position.allFinite();
  if (finite) t.body.position = position, t.known = true;
  t.body.stale = stale || !finite;
  t.seen_s = seen_s;
}

std::vector<std::string> FollowerView::setLost(const std::vector<std::string>& names) {
  std::vector<std::string> refused;
  lost_.clear();
  for (const std::string& n : names) {
    const auto k = kinds_.find(n);
    if (k != kinds_.end() && k->second.kind == task::EntityKind::Robot) lost_.insert(n);
    else refused.push_back(n);
  }
  return refused;
}

bool FollowerView::noteSegment(const std::string& name, uint32_t id, int step, const std::string& action,
                               const std::string& target, const Eigen::Vector2d& end,
                               std::vector<Eigen::Vector2d> way) {
  if (const auto e = ended_.find(name); e != ended_.end() && e->second == id) return false;
  forget(name);
  segments_[name] = {id, step, action, target, end, std::move(way)};
  bump(step);
  return true;
}

void FollowerView::noteEnded(const std::string& name, uint32_t id) {
  ended_[name] = id;
  if (const auto s = segments_.find(name); s != segments_.end() && s->second.id == id) forget(name);
}

void FollowerView::forget(const std::string& name) {
  const auto s = segments_.find(name);
  if (s == segments_.end()) return;
  bump(s->second.step);
  segments_.erase(s);
}

void FollowerView::bump(int step) {
  ++versions_[step];
}

uint64_t FollowerView::stepVersion(int step) const {
  const auto v = versions_.find(step);
  return v == versions_.end() ? 0 : v->second;
}

bool FollowerView::isObject(const std::string& name) const {
  const auto k = kinds_.find(name);
  return k != kinds_.end() && k->second.kind == task::EntityKind::Object;
}

double FollowerView::stopToward(const std::string& robot, int step, const std::string& action,
                                const std::string& target, double stop) const {
  if (!bodies_.count(target)) return stop;  // a goal is driven onto
  for (const auto& [name, s] : segments_)   // a carrier: its load is what ends at the target
    if (name != robot && s.step == step && s.action == action && s.target == target && isObject(name)) return stop;
  return stopAtPlace(stop);
}

double FollowerView::stopAtPlace(double stop) const {
  return task::stopRadiusAgainstBody(stop, std::max(task::kArrivalToleranceM, arrival_m_ - stop));
}

MotionContacts FollowerView::contacts(const std::string& robot, const Eigen::Vector2d& position) const {
  const auto own = segments_.find(robot);
  if (own == segments_.end()) return {};
  std::vector<BodyAtStart> at;
  for (const auto& [name, t] : bodies_) {
    if (name == robot) continue;
    BodyAtStart b;
    b.name = name, b.position = b.final_position = t.body.position, b.radius_m = t.body.radius_m;
    if (const auto s = segments_.find(name); s != segments_.end()) {
      b.final_position = s->second.end;
      b.object = isObject(name);
      b.step = s->second.step, b.action = s->second.action, b.target = s->second.target;
      b.way = s->second.way;
    }
    at.push_back(b);
  }
  const Segment& s = own->second;
  return motionContacts(position, radiusOf(robot), s.end, s.step, s.action, s.target, at, reach_m_, arrival_m_, s.way);
}

const std::vector<SafetyBody>& FollowerView::others(const std::string& robot, double now_s, double& self_age_s) {
  others_.clear();
  self_age_s = 1e9;
  for (const auto& [name, t] : bodies_) {
    if (name == robot) {
      self_age_s = t.body.stale ? 1e9 : now_s - t.seen_s;
      continue;
    }
    others_.push_back(t.body);
    others_.back().age_s = now_s - t.seen_s;
    others_.back().standing = !segments_.count(name);
    if (lost_.count(name) && t.known) {  // where it was last seen, for good
      others_.back().stale = false;
      others_.back().age_s = 0;
      others_.back().standing = true;
    }
  }
  return others_;
}

double FollowerView::radiusOf(const std::string& name) const {
  const auto t = bodies_.find(name);
  return t != bodies_.end() ? t->second.body.radius_m
                            : bodyShape(task::Entity{name, task::EntityKind::Robot, ""}).radius_m;
}

}  // namespace ddace::exec
