#include "ddace/task/end_point.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/error.h"

namespace ddace::task {

namespace {

using Eigen::Vector2d;

/// The approach frame's x axis: the unit vector from `start` toward `target` (zero when
/// they are closer than kMinApproachM).
Vector2d approach(const Vector2d& start, const Vector2d& target) {
  const Vector2d d = target - start;
  const double n = d.norm();
  return n < kMinApproachM ? Vector2d::Zero() : Vector2d(d / n);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Component-wise median of `offsets`.
EndOffset medianOffset(const std::vector<Vector2d>& offsets) {
  std::vector<double> x, y;
  for (const auto& o : offsets) x.push_back(o.x()), y.push_back(o.y());
  return {Vector2d(median(x), median(y)), static_cast<int>(offsets.size())};
}

}  // namespace

int carriedLoad(const TaskSpec& spec, const std::vector<Token>& step, size_t i) {
  const Token& t = step.at(i);
  if (!t.isMotion() || spec.entities.at(static_cast<size_t>(t.entity)).kind != EntityKind::Robot) return -1;
  for (size_t j = 0; j < step.size(); ++j)
    if (j != i && step[j].action == t.action && step[j].target == t.target &&
        spec.entities.at(static_cast<size_t>(step[j].entity)).kind == EntityKind::Object)
      return static_cast<int>(j);
  return -1;
}

std::string motionClass(const TaskSpec& spec, const std::vector<Token>& step, size_t i) {
  const Token& t = step.at(i);
  return std::string(toString(spec.entities.at(static_cast<size_t>(t.entity)).kind)) +
         (carriedLoad(spec, step, i) >= 0 ? "+load" : "") + "->" +
         toString(spec.entities.at(static_cast<size_t>(t.target)).kind);
}

EndPointModel learnEndPoints(const TaskSpec& spec, const std::vector<Demonstration>& demos) {
  std::map<std::string, std::vector<Vector2d>> keys, classes;
  for (const Demonstration& d : demos) {
    for (const Segment& seg : d.segments) {
      if (!seg.token.isMotion() || seg.step >= static_cast<int>(d.steps.size()) ||
          seg.step >= static_cast<int>(d.snapshots.size()))
        continue;
      const std::vector<Vector2d>& decided = d.snapshots[static_cast<size_t>(seg.step)].positions;
      const Vector2d s = decided.at(static_cast<size_t>(seg.token.entity));
      const Vector2d p = decided.at(static_cast<size_t>(seg.token.target));
      const Vector2d u = approach(s, p);
      if (u.isZero()) continue;
      const Vector2d rel =
          d.positions.at(static_cast<size_t>(seg.last_row)).at(static_cast<size_t>(seg.token.entity)) - p;
      const Vector2d offset(rel.dot(u), rel.dot(Vector2d(-u.y(), u.x())));
      const std::vector<Token>& step = d.steps[static_cast<size_t>(seg.step)].tokens;
      const auto at = std::find(step.begin(), step.end(), seg.token);
      if (at == step.end()) continue;
      keys[tokenKey(seg.token, spec)].push_back(offset);
      classes[motionClass(spec, step, static_cast<size_t>(at - step.begin()))].push_back(offset);
    }
  }
  EndPointModel m;
  for (const auto& [k, v] : keys) m.by_key[k] = medianOffset(v);
  for (const auto& [c, v] : classes) m.by_class[c] = medianOffset(v);
  return m;
}

Vector2d endOffset(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i) {
  const Token& t = step.at(i);
  if (model.centres || !t.isMotion()) return Vector2d::Zero();
  if (auto k = model.by_key.find(tokenKey(t, spec)); k != model.by_key.end() && k->second.segments >= kMinKeySegments)
    return k->second.offset;
  if (auto c = model.by_class.find(motionClass(spec, step, i)); c != model.by_class.end() && c->second.segments > 0)
    return c->second.offset;
  // Nothing demonstrated: the bodies decide. Toward an obstacle, contact; onto a flat goal.
  const Footprint mover = spec.footprint(t.entity), target = spec.footprint(t.target);
  const int load = carriedLoad(spec, step, i);
  if (load < 0) return Vector2d(target.obstacle ? -(mover.radius_m + target.radius_m) : 0.0, 0.0);
  const Footprint carried = spec.footprint(step[static_cast<size_t>(load)].entity);
  const double load_end = target.obstacle ? carried.radius_m + target.radius_m : 0.0;
  return Vector2d(-(load_end + carried.radius_m + mover.radius_m), 0.0);
}

Vector2d endPointFrom(const Vector2d& start, const Vector2d& target, const Vector2d& offset) {
  const Vector2d u = approach(start, target);
  if (u.isZero()) return start;
  return target + offset.x() * u + offset.y() * Vector2d(-u.y(), u.x());
}

Vector2d endPoint(const TaskSpec& spec, const EndPointModel& model, const std::vector<Token>& step, size_t i,
                  const std::vector<Vector2d>& decided) {
  const Token& t = step.at(i);
  const auto n = static_cast<int>(decided.size());
  if (t.entity < 0 || t.entity >= n || t.target >= n)
    throw Error("end point of a token naming an entity outside the " + std::to_string(n) + " positions given");
  if (!t.isMotion()) return decided[static_cast<size_t>(t.entity)];
  return endPointFrom(decided[static_cast<size_t>(t.entity)], decided[static_cast<size_t>(t.target)],
                      endOffset(spec, model, step, i));
}

Vector2d segmentEndPoint(const TaskSpec& spec, const EndPointModel& model, const Demonstration& demo,
                         const Segment& segment) {
  const auto k = static_cast<size_t>(segment.step);
  if (segment.step < 0 || k >= demo.steps.size() || k >= demo.snapshots.size()) return demo.segmentGoal(segment);
  const std::vector<Token>& step = demo.steps[k].tokens;
  const auto at = std::find(step.begin(), step.end(), segment.token);
  if (at == step.end()) return demo.segmentGoal(segment);
  return endPoint(spec, model, step, static_cast<size_t>(at - step.begin()), demo.snapshots[k].positions);
}

bool arrived(const Vector2d& position, const Vector2d& end_point, double arrival_radius) {
  return (position - end_point).norm() <= arrival_radius;
}

double togetherDistance(const TaskSpec& spec, int a, int b) {
  const Footprint fa = spec.footprint(a), fb = spec.footprint(b);
  const double contact = fa.obstacle && fb.obstacle ? fa.radius_m + fb.radius_m : 0.0;
  return std::max(2.0 * spec.arrival_radius, contact + spec.arrival_radius);
}

double stopRadius(double arrival_radius, double tolerance) {
  return std::max(arrival_radius - tolerance, 0.5 * arrival_radius);
}

}  // namespace ddace::task
