#include "ddace/gp/primitives.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>
#include <sstream>
#include <tuple>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/yaml_checker.h"
#include "ddace/gp/canonical.h"

namespace ddace::gp {

namespace {

Eigen::VectorXd progressGrid(int points) {
  return Eigen::VectorXd::LinSpaced(points, 0.0, 1.0);
}

std::string joinKey(const std::string& entity, const std::string& action, const std::string& target) {
  return entity + ":" + action + ":" + target;
}

using Canonical = std::vector<Eigen::Vector2d>;

/// The per-progress mean and within-progress sum of squares of `segments` on one axis: all
/// a GP of repeated inputs needs.
RepeatedData repeatedData(const std::vector<const Canonical*>& segments, int points, int axis) {
  RepeatedData d;
  const auto n = static_cast<double>(segments.size());
  d.inputs = progressGrid(points);
  d.counts = Eigen::VectorXd::Constant(points, n);
  d.means = Eigen::VectorXd::Zero(points);
  d.total = points * n;
  for (const Canonical* path : segments)
    for (int i = 0; i < points; ++i) d.means[i] += (*path)[i][axis];
  d.means /= n;
  for (const Canonical* path : segments)
    for (int i = 0; i < points; ++i) d.residual_ss += std::pow((*path)[i][axis] - d.means[i], 2);
  return d;
}

/// How well grouping `segments` by `group` predicts a held-out one: each segment against the
/// mean of the others of its group (a group of one: of all the others), the RMS distance
/// over progress, summed (canonical units).
double heldOutError(const std::vector<const Canonical*>& segments, const std::vector<int>& group) {
  const size_t n = segments.size(), points = segments.front()->size();
  std::map<int, std::pair<Canonical, int>> sums;
  Canonical all(points, Eigen::Vector2d::Zero());
  for (size_t k = 0; k < n; ++k) {
    auto& [sum, count] = sums[group[k]];
    if (sum.empty()) sum.assign(points, Eigen::Vector2d::Zero());
    for (size_t i = 0; i < points; ++i) sum[i] += (*segments[k])[i], all[i] += (*segments[k])[i];
    ++count;
  }
  double total = 0;
  for (size_t k = 0; k < n; ++k) {
    const auto& [sum, count] = sums.at(group[k]);
    const bool alone = count == 1;
    const Canonical& from = alone ? all : sum;
    const double others = alone ? static_cast<double>(n - 1) : count - 1;
    double ss = 0;
    for (size_t i = 0; i < points; ++i) {
      const Eigen::Vector2d x = (*segments[k])[i];
      ss += ((from[i] - x) / others - x).squaredNorm();
    }
    total += std::sqrt(ss / static_cast<double>(points));
  }
  return total;
}

/// Whether two groupings of the same segments are one partition.
bool samePartition(const std::vector<int>& a, const std::vector<int>& b) {
  std::map<int, int> ab, ba;
  for (size_t k = 0; k < a.size(); ++k)
    if (ab.emplace(a[k], b[k]).first->second != b[k] || ba.emplace(b[k], a[k]).first->second != a[k]) return false;
  return true;
}

// The fields of primitives.yaml through the one YamlChecker: each records its
// diagnostic (file:line:column) and says whether the value is usable, so a file is
// refused with every problem at once. `where` prefixes the field's name in messages.
bool textField(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where,
               std::string& out) {
  const YAML::Node n = c.required(map, key, where);
  return n && c.scalar(n, where + key, out);
}

bool number(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where, double& out) {
  const YAML::Node n = c.required(map, key, where);
  return n && c.number(n, where + key, out);
}

bool positive(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where, double& out) {
  const YAML::Node n = c.required(map, key, where);
  return n && c.positive(n, where + key, out);
}

bool nonNegative(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where, double& out) {
  const YAML::Node n = c.required(map, key, where);
  double v = 0;
  if (!n || !c.number(n, where + key, v)) return false;
  if (v < 0) {
    c.error(n, where + key + " must not be negative (got " + n.Scalar() + ")");
    return false;
  }
  out = v;
  return true;
}

bool boolean(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where, bool& out) {
  const YAML::Node n = c.required(map, key, where);
  return n && c.boolean(n, where + key, out);
}

/// A whole number in [lo, hi] (a fraction is an error, never truncated).
bool integer(YamlChecker& c, const YAML::Node& map, const std::string& key, const std::string& where, int lo, int hi,
             int& out) {
  const YAML::Node n = c.required(map, key, where);
  return n && c.integer(n, where + key, lo, hi, out);
}

/// Whether `name` is an end point class "KIND[+load]->KIND" (with `role`: and "@STEP"),
/// setting `motion_class` and `step`.
bool endPointClass(const std::string& name, bool role, std::string& motion_class, int& step) {
  motion_class = name;
  if (role) {
    const auto at = name.rfind('@');
    const std::string digits = at == std::string::npos ? "" : name.substr(at + 1);
    if (digits.empty() || digits.size() > 6 ||
        !std::all_of(digits.begin(), digits.end(), [](unsigned char ch) { return std::isdigit(ch) != 0; }))
      return false;
    step = std::stoi(digits);
    motion_class = name.substr(0, at);
  }
  const auto kind = [](const std::string& k) { return k == "robot" || k == "object" || k == "goal"; };
  const auto arrow = motion_class.find("->");
  std::string mover = arrow == std::string::npos ? "" : motion_class.substr(0, arrow);
  if (mover.size() > 5 && mover.substr(mover.size() - 5) == "+load") mover.resize(mover.size() - 5);
  return arrow != std::string::npos && kind(mover) && kind(motion_class.substr(arrow + 2));
}

/// end_points: {by_key: [{motion, offset: [x, y], segments}], by_class: [...], by_role:
/// [...] (`roles`: a /5 library's; motion "CLASS@STEP")}.
void readEndPoints(YamlChecker& c, const YAML::Node& root, const std::vector<std::string>& entities, bool roles,
                   task::EndPointModel& model) {
  const YAML::Node ends = c.required(root, "end_points", "", "where the demonstrated motions ended; retrain the model");
  if (!ends || !c.expectMap(ends, "end_points")) return;
  c.onlyKeys(
      ends,
      roles ? std::set<std::string>{"by_key", "by_class", "by_role"} : std::set<std::string>{"by_key", "by_class"},
      "end_points");
  auto known = [&](const std::string& name) {
    return std::find(entities.begin(), entities.end(), name) != entities.end();
  };
  for (const char* group : {"by_key", "by_class", "by_role"}) {
    const bool by_key = std::string(group) == "by_key", by_role = std::string(group) == "by_role";
    if (by_role && !roles) continue;
    const YAML::Node list = c.required(ends, group, "end_points: ");
    if (!list) continue;
    if (!list.IsSequence()) {
      c.error(list, std::string("end_points: ") + group + " must be a list");
      continue;
    }
    for (const auto& node : list) {
      if (!c.expectMap(node, std::string("an entry of end_points: ") + group)) continue;
      c.onlyKeys(node, {"motion", "offset", "segments"}, std::string("an entry of end_points: ") + group);
      std::string name, motion_class;
      int step = -1;
      task::EndOffset e;
      bool ok = textField(c, node, "motion", "end point ", name);
      if (ok && by_key) {
        const auto a = name.find(':'), b = name.rfind(':');
        ok = a != std::string::npos && b > a + 1 && known(name.substr(0, a)) && known(name.substr(b + 1));
        if (!ok)
          c.error(node["motion"], "end point key '" + name + "' is not ENTITY:ACTION:TARGET of the library's entities");
      } else if (ok) {
        ok = endPointClass(name, by_role, motion_class, step);
        if (!ok)
          c.error(node["motion"], "end point " + std::string(by_role ? "role" : "class") + " '" + name + "' is not " +
                                      (by_role ? "KIND[+load]->KIND@STEP" : "KIND[+load]->KIND") +
                                      " (robot, object, goal)");
      }
      const YAML::Node off = c.required(node, "offset", "end point " + name + ": ");
      if (off && (!off.IsSequence() || off.size() != 2)) {
        c.error(off, "end point " + name + ": offset must be [x, y] (metres)");
        ok = false;
      } else if (off) {
        for (int i = 0; i < 2; ++i) {
          double v = 0;
          if (!c.number(off[i], "end point " + name + ": offset", -kMaxEndOffsetM, kMaxEndOffsetM, v)) ok = false;
          e.offset[i] = v;
        }
      } else {
        ok = false;
      }
      ok = integer(c, node, "segments", "end point " + name + ": ", 1, kMaxPrimitiveSegments, e.segments) && ok;
      const bool fresh = !ok       ? true
                         : by_role ? model.by_role[motion_class].emplace(step, e).second
                         : by_key  ? model.by_key.emplace(name, e).second
                                   : model.by_class.emplace(name, e).second;
      if (!fresh) c.error(node["motion"], "end point " + name + " appears twice");
    }
  }
}

void emitGp(YAML::Emitter& out, const GaussianProcess& gp) {
  const KernelParams& p = gp.params();
  out << YAML::BeginMap;
  out << YAML::Key << "use_constant" << YAML::Value << gp.usesConstant();
  out << YAML::Key << "constant" << YAML::Value << p.constant;
  out << YAML::Key << "length_scale" << YAML::Value << p.length_scale;
  out << YAML::Key << "noise_level" << YAML::Value << p.noise_level;
  out << YAML::Key << "alpha" << YAML::Value << gp.alpha();
  out << YAML::Key << "residual_ss" << YAML::Value << gp.data().residual_ss;
  out << YAML::Key << "log_marginal_likelihood" << YAML::Value << gp.logMarginalLikelihood();
  out << YAML::Key << "means" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (Eigen::Index i = 0; i < gp.data().means.size(); ++i) out << gp.data().means[i];
  out << YAML::EndSeq << YAML::EndMap;
}

/// One axis' GP; false (with every problem recorded) when it cannot be rebuilt. Its
/// fields are always checked; it is conditioned (points x points matrices, cubic time) and
/// its likelihood compared only with `condition`.
bool readGp(YamlChecker& c, const YAML::Node& node, int points, int segments, const std::string& what, bool condition,
            GaussianProcess& out) {
  if (!c.expectMap(node, what)) return false;
  const std::string where = what + ": ";
  c.onlyKeys(node,
             {"use_constant", "constant", "length_scale", "noise_level", "alpha", "residual_ss",
              "log_marginal_likelihood", "means"},
             what);
  const size_t errors = c.errors().size();
  RepeatedData data;
  data.inputs = progressGrid(points);
  data.counts = Eigen::VectorXd::Constant(points, segments);
  data.total = static_cast<double>(points) * segments;
  data.means.resize(points);
  const YAML::Node means = c.required(node, "means", where);
  if (means && (!means.IsSequence() || static_cast<int>(means.size()) != points)) {
    c.error(means, where + "'means' must be a list of " + std::to_string(points) + " numbers");
  } else if (means) {
    for (int i = 0; i < points; ++i) c.number(means[i], where + "means[" + std::to_string(i) + "]", data.means[i]);
  }
  KernelParams p;
  bool use_constant = true;
  double alpha = 0, stored = 0;
  nonNegative(c, node, "residual_ss", where, data.residual_ss);
  if (boolean(c, node, "use_constant", where, use_constant) && use_constant)
    positive(c, node, "constant", where, p.constant);
  else p.constant = 1.0;
  positive(c, node, "length_scale", where, p.length_scale);
  positive(c, node, "noise_level", where, p.noise_level);
  nonNegative(c, node, "alpha", where, alpha);
  number(c, node, "log_marginal_likelihood", where, stored);
  if (c.errors().size() != errors || !condition) return false;
  try {
    out = GaussianProcess::condition(data, p, use_constant, alpha);
  } catch (const Error& e) {
    c.error(node, where + e.what());
    return false;
  }
  // The likelihood depends on every stored number: a corrupted or hand-edited value shows here.
  if (std::abs(out.logMarginalLikelihood() - stored) > 1e-6 * (1 + std::abs(stored))) {
    std::ostringstream msg;
    msg.precision(10);
    msg << where << "the stored log marginal likelihood " << stored << " does not match the stored data and "
        << "hyper-parameters (" << out.logMarginalLikelihood() << "); the file was corrupted or edited";
    c.error(node, msg.str());
    return false;
  }
  return true;
}

}  // namespace

std::string motionClass(const std::string& entity_kind, const std::string& action, const std::string& target_kind) {
  return entity_kind + "/" + action + "/" + target_kind;
}

std::string roleKey(const std::string& motion_class, int step) {
  return motion_class + "@" + std::to_string(step);
}

GpOptions defaultPrimitiveGpOptions() {
  GpOptions o;
  o.use_constant = true;
  o.alpha = 1e-10;
  o.initial = {0.1, 0.2, 1e-4};
  o.constant_bounds = {1e-4, 1e2};
  o.length_scale_bounds = {1e-2, 10.0};
  o.noise_bounds = {1e-6, 1.0};
  o.restarts = 2;
  o.seed = 0;
  return o;
}

std::map<std::string, KeySegments> canonicalSegments(const task::TaskDir& train, const PrimitiveOptions& options) {
  if (options.points < 2 || options.points > kMaxPrimitivePoints)
    throw Error("primitive option points must be in 2.." + std::to_string(kMaxPrimitivePoints));
  if (!(options.min_segment_length_m > 0)) throw Error("primitive option min_segment_length_m must be positive");
  std::map<std::string, KeySegments> by_key;
  for (const auto& demo : train.demos) {
    for (const auto& seg : demo.segments) {
      if (!seg.token.isMotion()) continue;
      KeySegments& c = by_key[task::tokenKey(seg.token, train.spec)];
      c.token = seg.token;
      const std::vector<Eigen::Vector2d> path = demo.segmentPath(seg);
      if ((path.back() - path.front()).norm() < options.min_segment_length_m) {
        ++c.skipped;
        continue;
      }
      const CanonicalFrame frame(path.front(), path.back());
      c.canonical.push_back(frame.toCanonical(resampleByProgress(path, options.points)));
      c.steps.push_back(seg.step);
    }
  }
  return by_key;
}

PrimitiveLibrary PrimitiveLibrary::fit(const task::TaskDir& train, const PrimitiveOptions& options) {
  const std::map<std::string, KeySegments> by_key = canonicalSegments(train, options);
  PrimitiveLibrary lib;
  lib.task_ = train.spec.name;
  lib.entities_ = train.spec.entityNames();
  lib.fingerprint_ = task::fingerprintOf(train);
  lib.kinds_ = lib.trained_kinds_ = kindsOf(lib.fingerprint_);
  lib.options_ = options;
  lib.end_points_ = task::learnEndPoints(train.spec, train.demos);
  const int n = options.points;
  const auto fitted = [&](Primitive p, const std::vector<const Canonical*>& segments) {
    p.segments = static_cast<int>(segments.size());
    p.x = GaussianProcess::fit(repeatedData(segments, n, 0), options.gp);
    p.y = GaussianProcess::fit(repeatedData(segments, n, 1), options.gp);
    return p;
  };
  // Each class's segments, grouped once by key and once by step (header comment, "Roles").
  struct Class {
    std::vector<const Canonical*> segments;
    std::vector<int> by_key, by_step;
  };
  std::map<std::string, Class> classes;
  int key_index = 0;
  for (const auto& [key, c] : by_key) {
    Primitive p;
    p.key = key;
    p.entity = train.spec.entities[c.token.entity].name;
    p.action = c.token.action;
    p.target = train.spec.entities[c.token.target].name;
    p.skipped_segments = c.skipped;
    std::vector<const Canonical*> segments;
    for (const auto& path : c.canonical) segments.push_back(&path);
    if (segments.empty()) continue;  // nothing usable: generation falls back for this key
    Class& cls = classes[motionClass(lib.kinds_.at(p.entity), p.action, lib.kinds_.at(p.target))];
    for (size_t k = 0; k < segments.size(); ++k) {
      cls.segments.push_back(segments[k]);
      cls.by_key.push_back(key_index);
      cls.by_step.push_back(c.steps[k]);
    }
    ++key_index;
    lib.primitives_.emplace(key, fitted(std::move(p), segments));
  }
  for (const auto& [name, cls] : classes) {
    if (cls.segments.size() < 2 || samePartition(cls.by_key, cls.by_step) ||
        !(heldOutError(cls.segments, cls.by_step) < heldOutError(cls.segments, cls.by_key)))
      continue;  // keyed by name
    std::map<int, std::vector<const Canonical*>> by_step;
    for (size_t k = 0; k < cls.segments.size(); ++k) by_step[cls.by_step[k]].push_back(cls.segments[k]);
    const auto a = name.find('/'), b = name.rfind('/');
    for (const auto& [step, segments] : by_step) {
      const std::string key = roleKey(name, step);
      Primitive p;
      p.key = key;
      p.entity = name.substr(0, a);
      p.action = name.substr(a + 1, b - a - 1);
      p.target = name.substr(b + 1);
      p.step = step;
      lib.primitives_.emplace(key, fitted(std::move(p), segments));
    }
  }
  lib.indexRoles();
  lib.cacheGrid();
  return lib;
}

void PrimitiveLibrary::indexRoles() {
  roles_.clear();
  for (const auto& [key, p] : primitives_)
    if (p.step >= 0) roles_[motionClass(p.entity, p.action, p.target)][p.step] = key;
}

std::vector<std::string> PrimitiveLibrary::roleClasses() const {
  std::vector<std::string> out;
  for (const auto& entry : roles_) out.push_back(entry.first);
  return out;
}

void PrimitiveLibrary::cacheGrid() {
  grid_.clear();
  const Eigen::VectorXd s = progressGrid(options_.points);
  for (const auto& [key, p] : primitives_) {
    Eigen::VectorXd mx, my, sx, sy;
    p.x.predict(s, mx, &sx);
    p.y.predict(s, my, &sy);
    auto& [mean, sd] = grid_[key];
    for (int i = 0; i < options_.points; ++i) {
      mean.emplace_back(mx[i], my[i]);
      sd.emplace_back(sx[i], sy[i]);
    }
  }
}

void PrimitiveLibrary::canonical(const Primitive& primitive, int points, std::vector<Eigen::Vector2d>& mean,
                                 std::vector<Eigen::Vector2d>& stddev) const {
  if (points < 2) throw Error("a path needs at least 2 points, got " + std::to_string(points));
  auto cached = grid_.find(primitive.key);
  if (points == options_.points && cached != grid_.end()) {
    mean = cached->second.first;
    stddev = cached->second.second;
  } else {
    const Eigen::VectorXd s = progressGrid(points);
    Eigen::VectorXd mx, my, sx, sy;
    primitive.x.predict(s, mx, &sx);
    primitive.y.predict(s, my, &sy);
    mean.resize(points);
    stddev.resize(points);
    for (int i = 0; i < points; ++i) {
      mean[i] = {mx[i], my[i]};
      stddev[i] = {sx[i], sy[i]};
    }
  }
  if (options_.pin_endpoints) {
    const Eigen::Vector2d first = mean.front(), last_error = Eigen::Vector2d(1, 0) - mean.back();
    for (int i = 0; i < points; ++i) {
      const double s = static_cast<double>(i) / (points - 1);
      mean[i] += (1 - s) * (-first) + s * last_error;
    }
  }
}

const Primitive* PrimitiveLibrary::lookup(const std::string& entity, const std::string& action,
                                          const std::string& target, int step, bool& fell_back) const {
  fell_back = false;
  // Kinds: of the requested names in the task tokens name (bound: boundTo's), of the
  // primitives' in the training task.
  const auto kindIn = [](const std::map<std::string, std::string>& kinds, const std::string& name) {
    const auto it = kinds.find(name);
    return it == kinds.end() ? std::string() : it->second;
  };
  const std::string entity_kind = kindIn(kinds_, entity), target_kind = kindIn(kinds_, target);
  // A class keyed by role: its primitive of the step, or of the nearest demonstrated one
  // (the earlier on a tie).
  const auto role = roles_.find(motionClass(entity_kind, action, target_kind));
  if (step >= 0 && role != roles_.end()) {
    const std::map<int, std::string>& steps = role->second;
    auto chosen = steps.lower_bound(step);
    if (chosen == steps.end() || (chosen != steps.begin() && step - std::prev(chosen)->first <= chosen->first - step))
      chosen = chosen == steps.begin() ? chosen : std::prev(chosen);
    fell_back = chosen->first != step;
    return &primitives_.at(chosen->second);
  }
  auto exact = primitives_.find(joinKey(entity, action, target));
  if (exact != primitives_.end()) return &exact->second;
  fell_back = true;
  // primitives_ is ordered by key, so the first of equally many segments wins the tie.
  const auto best = [&](bool same_entity, bool same_kinds) -> const Primitive* {
    const Primitive* chosen = nullptr;
    for (const auto& [key, p] : primitives_) {
      if (p.step >= 0 || p.action != action || (same_entity && p.entity != entity)) continue;
      if (same_kinds &&
          (kindIn(trained_kinds_, p.entity) != entity_kind || kindIn(trained_kinds_, p.target) != target_kind))
        continue;
      if (!chosen || p.segments > chosen->segments) chosen = &p;
    }
    return chosen;
  };
  // The same entity toward a target of the same kind; the same action by an entity of its
  // kind toward one of the target's kind (a robot the library never saw); then any.
  const std::pair<bool, bool> order[] = {{true, true}, {false, true}, {true, false}, {false, false}};
  for (const auto& [same_entity, same_kinds] : order)
    if (const Primitive* p = best(same_entity, same_kinds)) return p;
  return nullptr;
}

GeneratedPath PrimitiveLibrary::generateFrom(const Primitive* primitive, bool fell_back, const Eigen::Vector2d& start,
                                             const Eigen::Vector2d& goal, int points) const {
  if (points < 2) throw Error("a path needs at least 2 points, got " + std::to_string(points));
  if (!start.allFinite() || !goal.allFinite()) throw Error("path start and goal must be finite");
  GeneratedPath out;
  out.fell_back = fell_back;
  out.source_key = primitive ? primitive->key : kStraightLine;
  const double d = (goal - start).norm();
  if (d < kMinMotionLength) {
    out.points.assign(points, start);
    out.stddev.assign(points, 0.0);
    return out;
  }
  const CanonicalFrame frame(start, goal);
  if (!primitive) {
    for (int i = 0; i < points; ++i) {
      const double s = static_cast<double>(i) / (points - 1);
      out.points.push_back(start + s * (goal - start));
    }
    out.points.back() = goal;
    out.stddev.assign(points, 0.0);
    return out;
  }
  std::vector<Eigen::Vector2d> mean, sd;
  canonical(*primitive, points, mean, sd);
  out.points = frame.fromCanonical(mean);
  if (options_.pin_endpoints) {
    out.points.front() = start;  // exact, not start + rounding
    out.points.back() = goal;
  }
  out.stddev.reserve(points);
  for (const auto& v : sd) out.stddev.push_back(d * std::sqrt(0.5 * v.squaredNorm()));
  return out;
}

GeneratedPath PrimitiveLibrary::generate(const task::Token& token, const Eigen::Vector2d& start,
                                         const Eigen::Vector2d& goal, int points, int step) const {
  const int m = static_cast<int>(entities_.size());
  if (token.entity < 0 || token.entity >= m)
    throw Error("token entity index " + std::to_string(token.entity) + " is not an entity of task '" + task_ + "'");
  if (!token.isMotion())
    throw Error("token " + entities_[token.entity] + ":" + token.action + " is an in-place action: it has no path");
  if (token.target >= m)
    throw Error("token target index " + std::to_string(token.target) + " is not an entity of task '" + task_ + "'");
  bool fell_back = false;
  const Primitive* p = lookup(entities_[token.entity], token.action, entities_[token.target], step, fell_back);
  return generateFrom(p, fell_back, start, goal, points);
}

GeneratedPath PrimitiveLibrary::generate(const std::string& key, const Eigen::Vector2d& start,
                                         const Eigen::Vector2d& goal, int points, int step) const {
  // A role key as primitives() lists it ("KIND/ACTION/KIND@STEP") names its primitive.
  if (key.find('/') != std::string::npos) {
    const auto it = primitives_.find(key);
    if (it == primitives_.end())
      throw Error("key '" + key + "' is no role primitive of the library of task '" + task_ + "'");
    return generateFrom(&it->second, false, start, goal, points);
  }
  std::vector<std::string> parts;
  std::stringstream ss(key);
  for (std::string part; std::getline(ss, part, ':');) parts.push_back(part);
  if (parts.size() != 3 || parts[0].empty() || parts[1].empty() || parts[2].empty())
    throw Error("key '" + key + "' is not ENTITY:ACTION:TARGET");
  for (int i : {0, 2})
    if (std::find(entities_.begin(), entities_.end(), parts[i]) == entities_.end()) {
      std::string known;
      for (const auto& e : entities_) known += (known.empty() ? "" : ", ") + e;
      throw Error("key '" + key + "': '" + parts[i] + "' is not an entity of task '" + task_ + "' (" + known + ")");
    }
  if (parts[0] == parts[2]) throw Error("key '" + key + "': an entity cannot move toward itself");
  bool fell_back = false;
  const Primitive* p = lookup(parts[0], parts[1], parts[2], step, fell_back);
  return generateFrom(p, fell_back, start, goal, points);
}

std::map<std::string, std::string> PrimitiveLibrary::kindsOf(const task::TaskFingerprint& fingerprint) {
  std::map<std::string, std::string> kinds;  // "NAME:KIND" or "NAME:KIND:TYPE"
  for (const std::string& e : fingerprint.entities) kinds[e.substr(0, e.find(':'))] = e.substr(e.find(':') + 1);
  return kinds;
}

PrimitiveLibrary PrimitiveLibrary::boundTo(const task::TaskSpec& other) const {
  // The fingerprint's entities are "NAME:KIND" or "NAME:KIND:TYPE".
  std::set<std::string> mine, theirs;
  for (const std::string& e : fingerprint_.entities) mine.insert(e.substr(e.find(':') + 1));
  for (const std::string& e : task::fingerprintOf(other).entities) theirs.insert(e.substr(e.find(':') + 1));
  for (const auto& k : mine)
    if (!theirs.count(k)) throw Error("task '" + other.name + "' has no entity of kind " + k + ", the library's has");
  for (const auto& k : theirs)
    if (!mine.count(k)) throw Error("the library of task '" + task_ + "' was fitted on no entity of kind " + k);
  PrimitiveLibrary bound = *this;
  bound.entities_ = other.entityNames();
  bound.kinds_ = kindsOf(task::fingerprintOf(other));
  bound.trained_kinds_ = trained_kinds_;
  return bound;
}

void PrimitiveLibrary::save(const std::string& path) const {
  writeTextFile(path, text());  // checked and atomic: a failed write leaves the old file
}

std::string PrimitiveLibrary::text() const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment(
      "ddace motion-primitive library (docs/gp.md). One primitive per (entity, action, target),\n"
      "and per step of a motion class keyed by role (entity and target then name kinds):\n"
      "an x-GP and a y-GP of canonical coordinates over progress s = linspace(0, 1, points),\n"
      "kernel C*RBF(length_scale) + White(noise_level), trained on `segments` segments.\n"
      "`means`/`residual_ss` are the per-progress mean and the within-progress sum of squares\n"
      "of the training data: all a prediction needs. Written by ddace; do not edit.");
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kPrimitivesFormat;
  out << YAML::Key << "task" << YAML::Value << task_;
  out << YAML::Key << "entities" << YAML::Value << YAML::Flow << entities_;
  out << YAML::Key << "task_fingerprint" << YAML::Value;
  task::emitFingerprint(out, fingerprint_);
  out << YAML::Key << "points" << YAML::Value << options_.points;
  out << YAML::Key << "pin_endpoints" << YAML::Value << options_.pin_endpoints;
  out << YAML::Key << "min_segment_length_m" << YAML::Value << options_.min_segment_length_m;
  // Where the demonstrated motions ended: metres in the approach frame (task/end_point.h).
  out << YAML::Key << "end_points" << YAML::Value << YAML::BeginMap;
  const auto emitEnd = [&out](const std::string& name, const task::EndOffset& e) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "motion" << YAML::Value << name << YAML::Key << "offset"
        << YAML::Value << YAML::Flow << std::vector<double>{e.offset.x(), e.offset.y()} << YAML::Key << "segments"
        << YAML::Value << e.segments << YAML::EndMap;
  };
  for (const char* group : {"by_key", "by_class"}) {
    out << YAML::Key << group << YAML::Value << YAML::BeginSeq;
    for (const auto& [name, e] : std::string(group) == "by_key" ? end_points_.by_key : end_points_.by_class)
      emitEnd(name, e);
    out << YAML::EndSeq;
  }
  out << YAML::Key << "by_role" << YAML::Value << YAML::BeginSeq;
  for (const auto& [motion_class, steps] : end_points_.by_role)
    for (const auto& [step, e] : steps) emitEnd(motion_class + "@" + std::to_string(step), e);
  out << YAML::EndSeq;
  out << YAML::EndMap;
  out << YAML::Key << "primitives" << YAML::Value << YAML::BeginSeq;
  for (const auto& [key, p] : primitives_) {
    out << YAML::BeginMap;
    out << YAML::Key << "key" << YAML::Value << key;
    out << YAML::Key << "entity" << YAML::Value << p.entity;
    out << YAML::Key << "action" << YAML::Value << p.action;
    out << YAML::Key << "target" << YAML::Value << p.target;
    if (p.step >= 0) out << YAML::Key << "step" << YAML::Value << p.step;
    out << YAML::Key << "segments" << YAML::Value << p.segments;
    out << YAML::Key << "skipped_segments" << YAML::Value << p.skipped_segments;
    out << YAML::Key << "x" << YAML::Value;
    emitGp(out, p.x);
    out << YAML::Key << "y" << YAML::Value;
    emitGp(out, p.y);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

PrimitiveLibrary PrimitiveLibrary::load(const std::string& path) {
  return parse(readTextFile(path), path);
}

/// parse() in parts: the format, the entities and fingerprint, and each primitive, every
/// problem collected in one YamlChecker and thrown at once in file order.
class LibraryReader {
 public:
  LibraryReader(const std::string& text, const std::string& path) : text_(text), c_(path) {}

  PrimitiveLibrary read() {
    root_ = c_.parse(text_);
    c_.throwIfErrors();
    if (!root_.IsMap()) {
      c_.error(root_,
               "not a primitive library (expected a mapping with format: " + std::string(kPrimitivesFormat) + ")");
      c_.throwIfErrors();
    }
    readFormat();
    c_.throwIfErrors();  // another format's fields would only add noise to the one error that matters
    c_.onlyKeys(root_,
                {"format", "task", "entities", "task_fingerprint", "points", "pin_endpoints", "min_segment_length_m",
                 "end_points", "primitives"},
                "a primitive library");
    if (format_ == kPrimitivesFormatWithoutEndPoints) {
      lib_.end_points_.centres = true;
      if (root_["end_points"])
        c_.error(root_["end_points"], std::string(kPrimitivesFormatWithoutEndPoints) + " has no end_points");
    }
    textField(c_, root_, "task", "", lib_.task_);
    readEntities();
    // Bounded before anything is allocated from it (every GP holds points x points matrices).
    have_points_ = integer(c_, root_, "points", "", 2, kMaxPrimitivePoints, lib_.options_.points);
    boolean(c_, root_, "pin_endpoints", "", lib_.options_.pin_endpoints);
    positive(c_, root_, "min_segment_length_m", "", lib_.options_.min_segment_length_m);
    if (!lib_.end_points_.centres)
      readEndPoints(c_, root_, lib_.entities_, format_ == kPrimitivesFormat, lib_.end_points_);
    const YAML::Node prims = c_.required(root_, "primitives");
    if (prims && !prims.IsSequence()) c_.error(prims, "'primitives' must be a list");
    if (prims && prims.IsSequence())
      for (const auto& node : prims) readPrimitive(node);
    // In file order: a hand-edited file's keys may come in any order.
    std::vector<Diagnostic> all = c_.errors();
    std::stable_sort(all.begin(), all.end(), [](const Diagnostic& a, const Diagnostic& b) {
      return std::tie(a.line, a.column) < std::tie(b.line, b.column);
    });
    if (!all.empty()) throw Error(all);
    lib_.indexRoles();
    lib_.cacheGrid();
    return std::move(lib_);
  }

 private:
  void readFormat() {
    if (textField(c_, root_, "format", "", format_) && format_ != kPrimitivesFormat &&
        format_ != kPrimitivesFormatWithoutRoleEnds && format_ != kPrimitivesFormatWithoutRoles &&
        format_ != kPrimitivesFormatWithoutEndPoints)
      c_.error(root_["format"],
               "unsupported format '" + format_ + "' (expected " + kPrimitivesFormat +
                   (format_ == "ddace-primitives/1" ? "; this older library names no task: retrain the model" : "") +
                   ")");
  }

  /// 'entities' and the task fingerprint, which must name the same entities.
  void readEntities() {
    const YAML::Node entities = c_.required(root_, "entities");
    bool entities_ok = false;
    if (entities && (!entities.IsSequence() || entities.size() == 0)) {
      c_.error(entities, "'entities' must be a non-empty list of names");
    } else if (entities) {
      entities_ok = true;
      for (const auto& e : entities) {
        if (!e.IsScalar() || !task::isValidName(e.Scalar())) {
          c_.error(e, "invalid entity name");
          entities_ok = false;
        } else {
          lib_.entities_.push_back(e.Scalar());
        }
      }
    }
    const YAML::Node fp = c_.required(root_, "task_fingerprint");
    if (!fp || !task::parseFingerprint(c_, fp, lib_.fingerprint_)) return;
    std::vector<std::string> sorted = lib_.entities_;
    std::sort(sorted.begin(), sorted.end());
    std::vector<std::string> named;
    for (const auto& e : lib_.fingerprint_.entities) named.push_back(e.substr(0, e.find(':')));
    // The fingerprint sorts "NAME:KIND" strings, where R10:... comes before R1:... (':' > '0').
    std::sort(named.begin(), named.end());
    if (entities_ok && sorted != named) c_.error(fp, "task_fingerprint names other entities than 'entities'");
    lib_.kinds_ = lib_.trained_kinds_ = PrimitiveLibrary::kindsOf(lib_.fingerprint_);
  }

  bool knownEntity(const std::string& name) const {
    return std::find(lib_.entities_.begin(), lib_.entities_.end(), name) != lib_.entities_.end();
  }
  bool knownKind(const std::string& kind) const {
    for (const auto& entry : lib_.trained_kinds_)
      if (entry.second == kind) return true;
    return false;
  }

  /// The key of a primitive by name (its entity, action and target) or by role (its kinds,
  /// action and step: format /4); false when it names none.
  bool readKey(const YAML::Node& node, Primitive& p) {
    const bool named =
        YamlChecker::allOf({textField(c_, node, "key", "", p.key), textField(c_, node, "entity", "", p.entity),
                            textField(c_, node, "action", "", p.action), textField(c_, node, "target", "", p.target)});
    const std::string what = "primitive " + p.key;
    const bool role = static_cast<bool>(node["step"]);
    if (role && (format_ == kPrimitivesFormatWithoutRoles || format_ == kPrimitivesFormatWithoutEndPoints))
      c_.error(node["step"], what + ": a " + format_ + " library has no role primitives");
    else if (role) integer(c_, node, "step", what + ": ", 0, kMaxPrimitiveSegments, p.step);
    if (named && role) {
      for (const auto& [field, kind] : {std::pair{"entity", p.entity}, std::pair{"target", p.target}})
        if (!knownKind(kind)) c_.error(node[field], what + ": '" + kind + "' is no kind of the library's entities");
      if (p.key != roleKey(motionClass(p.entity, p.action, p.target), p.step))
        c_.error(node["key"], "primitive key '" + p.key + "' does not match its kinds, action and step");
    } else if (named) {
      if (!knownEntity(p.entity)) c_.error(node["entity"], what + ": unknown entity '" + p.entity + "'");
      if (!knownEntity(p.target)) c_.error(node["target"], what + ": unknown target '" + p.target + "'");
      if (p.key != joinKey(p.entity, p.action, p.target))
        c_.error(node["key"], "primitive key '" + p.key + "' does not match its entity, action and target");
    }
    if (named && lib_.primitives_.count(p.key)) c_.error(node["key"], what + " appears twice");
    return named;
  }

  void readPrimitive(const YAML::Node& node) {
    if (!c_.expectMap(node, "a primitive")) return;
    c_.onlyKeys(node, {"key", "entity", "action", "target", "step", "segments", "skipped_segments", "x", "y"},
                "a primitive");
    Primitive p;
    const bool named = readKey(node, p);
    const std::string what = "primitive " + p.key;
    const bool counted = integer(c_, node, "segments", what + ": ", 1, kMaxPrimitiveSegments, p.segments);
    const bool skipped_ok =
        integer(c_, node, "skipped_segments", what + ": ", 0, kMaxPrimitiveSegments, p.skipped_segments);
    const YAML::Node x = c_.required(node, "x", what + ": "), y = c_.required(node, "y", what + ": ");
    if (!have_points_ || !counted) return;  // a GP's size is unknown
    // Rebuilding GPs costs cubic time: only while the file is sound so far, and only for
    // as many numbers as the text can hold (YAML aliases are not part of the format).
    means_read_ += 2 * static_cast<size_t>(lib_.options_.points);
    if (2 * means_read_ > text_.size() && !aliased_) {
      c_.error(node, what + ": more numbers than the file has characters (YAML aliases are not accepted here)");
      aliased_ = true;
    }
    const bool condition = named && skipped_ok && !aliased_ && c_.errors().empty();
    const int points = lib_.options_.points;
    const bool fitted = YamlChecker::allOf({x && readGp(c_, x, points, p.segments, what + ", x", condition, p.x),
                                            y && readGp(c_, y, points, p.segments, what + ", y", condition, p.y)});
    if (fitted) lib_.primitives_.emplace(p.key, std::move(p));
  }

  const std::string& text_;
  YamlChecker c_;
  YAML::Node root_;
  std::string format_;
  PrimitiveLibrary lib_;
  bool have_points_ = false;
  size_t means_read_ = 0;
  bool aliased_ = false;
};

PrimitiveLibrary PrimitiveLibrary::parse(const std::string& text, const std::string& path) {
  return LibraryReader(text, path).read();
}

}  // namespace ddace::gp
