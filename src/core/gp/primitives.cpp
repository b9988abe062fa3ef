#include "ddace/gp/primitives.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/gp/canonical.h"

namespace ddace::gp {

namespace {

Eigen::VectorXd progressGrid(int points) {
  return Eigen::VectorXd::LinSpaced(points, 0.0, 1.0);
}

std::string joinKey(const std::string& entity, const std::string& action, const std::string& target) {
  return entity + ":" + action + ":" + target;
}

/// Field access with diagnostics that name the file, line and column.
struct Reader {
  std::string file;

  [[noreturn]] void fail(const YAML::Node& at, const std::string& message) const {
    const YAML::Mark m = at.Mark();
    throw Error(Diagnostic{file, m.line >= 0 ? m.line + 1 : 0, m.column >= 0 ? m.column + 1 : 0, message});
  }
  YAML::Node need(const YAML::Node& parent, const std::string& key) const {
    if (!parent.IsMap()) fail(parent, "expected a mapping holding '" + key + "'");
    const YAML::Node n = parent[key];
    if (!n.IsDefined() || n.IsNull()) fail(parent, "missing field '" + key + "'");
    return n;
  }
  double number(const YAML::Node& parent, const std::string& key) const {
    const YAML::Node n = need(parent, key);
    double v = 0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(n, "'" + key + "' must be a number");
    }
    if (!std::isfinite(v)) fail(n, "'" + key + "' must be a finite number");
    return v;
  }
  double positive(const YAML::Node& parent, const std::string& key) const {
    const double v = number(parent, key);
    if (!(v > 0)) fail(need(parent, key), "'" + key + "' must be positive");
    return v;
  }
  int integer(const YAML::Node& parent, const std::string& key, int min, int max) const {
    const YAML::Node n = need(parent, key);
    int v = 0;
    try {
      v = n.as<int>();
    } catch (const YAML::Exception&) {
      fail(n, "'" + key + "' must be an integer");
    }
    if (v < min || v > max) fail(n, "'" + key + "' must be in " + std::to_string(min) + ".." + std::to_string(max));
    return v;
  }
  bool boolean(const YAML::Node& parent, const std::string& key) const {
    const YAML::Node n = need(parent, key);
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail(n, "'" + key + "' must be true or false");
    }
  }
  std::string text(const YAML::Node& parent, const std::string& key) const {
    const YAML::Node n = need(parent, key);
    if (!n.IsScalar()) fail(n, "'" + key + "' must be text");
    return n.Scalar();
  }
};

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

GaussianProcess readGp(const Reader& r, const YAML::Node& node, int points, int segments, const std::string& what) {
  RepeatedData data;
  data.inputs = progressGrid(points);
  data.counts = Eigen::VectorXd::Constant(points, segments);
  data.total = static_cast<double>(points) * segments;
  const YAML::Node means = r.need(node, "means");
  if (!means.IsSequence() || static_cast<int>(means.size()) != points)
    r.fail(means, what + ": 'means' must be a list of " + std::to_string(points) + " numbers");
  data.means.resize(points);
  for (int i = 0; i < points; ++i) {
    try {
      data.means[i] = means[i].as<double>();
    } catch (const YAML::Exception&) {
      r.fail(means[i], what + ": means[" + std::to_string(i) + "] is not a number");
    }
    if (!std::isfinite(data.means[i])) r.fail(means[i], what + ": means[" + std::to_string(i) + "] is not finite");
  }
  data.residual_ss = r.number(node, "residual_ss");
  if (data.residual_ss < 0) r.fail(r.need(node, "residual_ss"), what + ": 'residual_ss' must not be negative");
  KernelParams p;
  const bool use_constant = r.boolean(node, "use_constant");
  p.constant = use_constant ? r.positive(node, "constant") : 1.0;
  p.length_scale = r.positive(node, "length_scale");
  p.noise_level = r.positive(node, "noise_level");
  const double alpha = r.number(node, "alpha");
  if (alpha < 0) r.fail(r.need(node, "alpha"), what + ": 'alpha' must not be negative");
  const double stored = r.number(node, "log_marginal_likelihood");
  GaussianProcess gp;
  try {
    gp = GaussianProcess::condition(data, p, use_constant, alpha);
  } catch (const Error& e) {
    r.fail(node, what + ": " + e.what());
  }
  // The likelihood depends on every stored number: a corrupted or hand-edited value shows here.
  if (std::abs(gp.logMarginalLikelihood() - stored) > 1e-6 * (1 + std::abs(stored))) {
    std::ostringstream msg;
    msg.precision(10);
    msg << what << ": the stored log marginal likelihood " << stored << " does not match the stored data and "
        << "hyper-parameters (" << gp.logMarginalLikelihood() << "); the file was corrupted or edited";
    r.fail(node, msg.str());
  }
  return gp;
}

}  // namespace

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
  lib.options_ = options;
  const int n = options.points;
  for (const auto& [key, c] : by_key) {
    Primitive p;
    p.key = key;
    p.entity = train.spec.entities[c.token.entity].name;
    p.action = c.token.action;
    p.target = train.spec.entities[c.token.target].name;
    p.segments = static_cast<int>(c.canonical.size());
    p.skipped_segments = c.skipped;
    if (p.segments == 0) continue;  // nothing usable: generation falls back for this key
    for (int axis = 0; axis < 2; ++axis) {
      RepeatedData d;
      d.inputs = progressGrid(n);
      d.counts = Eigen::VectorXd::Constant(n, p.segments);
      d.means = Eigen::VectorXd::Zero(n);
      d.total = static_cast<double>(n) * p.segments;
      for (const auto& path : c.canonical)
        for (int i = 0; i < n; ++i) d.means[i] += path[i][axis];
      d.means /= p.segments;
      for (const auto& path : c.canonical)
        for (int i = 0; i < n; ++i) d.residual_ss += std::pow(path[i][axis] - d.means[i], 2);
      (axis == 0 ? p.x : p.y) = GaussianProcess::fit(d, options.gp);
    }
    lib.primitives_.emplace(key, std::move(p));
  }
  lib.cacheGrid();
  return lib;
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
                                          const std::string& target, bool& fell_back) const {
  fell_back = false;
  auto exact = primitives_.find(joinKey(entity, action, target));
  if (exact != primitives_.end()) return &exact->second;
  fell_back = true;
  // primitives_ is ordered by key, so the first of equally many segments wins the tie.
  auto best = [&](bool same_entity) -> const Primitive* {
    const Primitive* chosen = nullptr;
    for (const auto& [key, p] : primitives_) {
      if (p.action != action || (same_entity && p.entity != entity)) continue;
      if (!chosen || p.segments > chosen->segments) chosen = &p;
    }
    return chosen;
  };
  if (const Primitive* p = best(true)) return p;
  return best(false);
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
                                         const Eigen::Vector2d& goal, int points) const {
  const int m = static_cast<int>(entities_.size());
  if (token.entity < 0 || token.entity >= m)
    throw Error("token entity index " + std::to_string(token.entity) + " is not an entity of task '" + task_ + "'");
  if (!token.isMotion())
    throw Error("token " + entities_[token.entity] + ":" + token.action + " is an in-place action: it has no path");
  if (token.target >= m)
    throw Error("token target index " + std::to_string(token.target) + " is not an entity of task '" + task_ + "'");
  bool fell_back = false;
  const Primitive* p = lookup(entities_[token.entity], token.action, entities_[token.target], fell_back);
  return generateFrom(p, fell_back, start, goal, points);
}

GeneratedPath PrimitiveLibrary::generate(const std::string& key, const Eigen::Vector2d& start,
                                         const Eigen::Vector2d& goal, int points) const {
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
  const Primitive* p = lookup(parts[0], parts[1], parts[2], fell_back);
  return generateFrom(p, fell_back, start, goal, points);
}

void PrimitiveLibrary::save(const std::string& path) const {
  writeTextFile(path, text());  // checked and atomic: a failed write leaves the old file
}

std::string PrimitiveLibrary::text() const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::Comment(
      "ddace motion-primitive library (docs/gp.md). One primitive per (entity, action, target):\n"
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
  out << YAML::Key << "primitives" << YAML::Value << YAML::BeginSeq;
  for (const auto& [key, p] : primitives_) {
    out << YAML::BeginMap;
    out << YAML::Key << "key" << YAML::Value << key;
    out << YAML::Key << "entity" << YAML::Value << p.entity;
    out << YAML::Key << "action" << YAML::Value << p.action;
    out << YAML::Key << "target" << YAML::Value << p.target;
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

PrimitiveLibrary PrimitiveLibrary::parse(const std::string& text, const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw Error(Diagnostic{path, e.mark.line + 1, e.mark.column + 1, "not valid YAML: " + e.msg});
  }
  const Reader r{path};
  if (!root.IsMap())
    r.fail(root, "not a primitive library (expected a mapping with format: " + std::string(kPrimitivesFormat) + ")");
  const std::string format = r.text(root, "format");
  if (format != kPrimitivesFormat)
    r.fail(root["format"],
           "unsupported format '" + format + "' (expected " + kPrimitivesFormat +
               (format == "ddace-primitives/1" ? "; this older library names no task: retrain the model" : "") + ")");

  PrimitiveLibrary lib;
  lib.task_ = r.text(root, "task");
  const YAML::Node entities = r.need(root, "entities");
  if (!entities.IsSequence() || entities.size() == 0) r.fail(entities, "'entities' must be a non-empty list of names");
  for (const auto& e : entities) {
    if (!e.IsScalar() || !task::isValidName(e.Scalar())) r.fail(e, "invalid entity name");
    lib.entities_.push_back(e.Scalar());
  }
  lib.fingerprint_ = task::parseFingerprint(r.need(root, "task_fingerprint"), path);
  {
    std::vector<std::string> sorted = lib.entities_;
    std::sort(sorted.begin(), sorted.end());
    std::vector<std::string> named;
    for (const auto& e : lib.fingerprint_.entities) named.push_back(e.substr(0, e.find(':')));
    // The fingerprint sorts "NAME:KIND" strings, where R10:... comes before R1:... (':' > '0').
    std::sort(named.begin(), named.end());
    if (sorted != named) r.fail(root["task_fingerprint"], "task_fingerprint names other entities than 'entities'");
  }
  // Bounded before anything is allocated from it (every GP holds points x points matrices).
  lib.options_.points = r.integer(root, "points", 2, kMaxPrimitivePoints);
  lib.options_.pin_endpoints = r.boolean(root, "pin_endpoints");
  lib.options_.min_segment_length_m = r.positive(root, "min_segment_length_m");
  const YAML::Node prims = r.need(root, "primitives");
  if (!prims.IsSequence()) r.fail(prims, "'primitives' must be a list");
  auto known = [&](const std::string& name) {
    return std::find(lib.entities_.begin(), lib.entities_.end(), name) != lib.entities_.end();
  };
  for (const auto& node : prims) {
    Primitive p;
    p.key = r.text(node, "key");
    p.entity = r.text(node, "entity");
    p.action = r.text(node, "action");
    p.target = r.text(node, "target");
    if (!known(p.entity)) r.fail(node["entity"], "primitive " + p.key + ": unknown entity '" + p.entity + "'");
    if (!known(p.target)) r.fail(node["target"], "primitive " + p.key + ": unknown target '" + p.target + "'");
    if (p.key != joinKey(p.entity, p.action, p.target))
      r.fail(node["key"], "primitive key '" + p.key + "' does not match its entity, action and target");
    if (lib.primitives_.count(p.key)) r.fail(node["key"], "primitive " + p.key + " appears twice");
    p.segments = r.integer(node, "segments", 1, kMaxPrimitiveSegments);
    p.skipped_segments = r.integer(node, "skipped_segments", 0, kMaxPrimitiveSegments);
    p.x = readGp(r, r.need(node, "x"), lib.options_.points, p.segments, "primitive " + p.key + ", x");
    p.y = readGp(r, r.need(node, "y"), lib.options_.points, p.segments, "primitive " + p.key + ", y");
    lib.primitives_.emplace(p.key, std::move(p));
  }
  lib.cacheGrid();
  return lib;
}

}  // namespace ddace::gp
