// The perturbation suite (include/ddace/pipeline/perturbation.h).
#include "ddace/pipeline/perturbation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <ostream>

#include <nlohmann/json.hpp>

#include "ddace/common/error.h"
#include "ddace/common/random.h"
#include "ddace/exec/bodies_execution.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/scene.h"
#include "ddace/exec/table_simulator.h"
#include "ddace/pipeline/decisions_without.h"
#include "ddace/task/body_geometry.h"
#include "ddace/tasks/rule_zoo.h"

namespace ddace::pipeline {
namespace {

constexpr double kCycleS = 0.02;  // the control rate, 50 Hz
/// A body a hand puts down lands at least this clear of every other (metres).
constexpr double kLandingGapM = 0.01;
/// A run not ended by then is cut; the coordinator's time-outs end a stuck one sooner.
constexpr double kMaxRunS = 600;

double lengthOf(const exec::Path& p) {
  double s = 0;
  for (size_t i = 1; i < p.size(); ++i) s += (p[i] - p[i - 1]).norm();
  return s;
}

/// The point `s` metres along `p`.
Eigen::Vector2d pointAt(const exec::Path& p, double s) {
  for (size_t i = 1; i < p.size(); ++i) {
    const double l = (p[i] - p[i - 1]).norm();
    if (s <= l && l > 0) return p[i - 1] + (p[i] - p[i - 1]) * (s / l);
    s -= l;
  }
  return p.back();
}

/// A run that lost a robot for good and aborted naming it (the goal where the run cannot go on
/// without it: never a finish with the task undone).
bool abortedNamingLost(const CoordinatedRun& run) {
  if (run.finished) return false;
  for (const std::string& l : run.lost)
    if (run.reason.find(l.substr(0, l.find(':'))) != std::string::npos) return true;
  return false;
}

/// A segment as the coordinator sent it, while it runs.
struct Mover {
  int entity = -1;
  uint32_t segment = 0;
  int step = 0;
  task::Token token;
  exec::Path path;
  double length = 0;
};

/// A segment that ended on the table.
struct SegmentEnd {
  int entity = -1;
  uint32_t segment = 0;
  bool done = false;
  std::string message;
};

/// The table under a coordinated run: every entity follows its segment, one control
/// cycle (kCycleS) at a time, and a hand may change it.
class Table {
 public:
  virtual ~Table() = default;
  /// Segments that go out together (one coordinator output), each replacing its entity's.
  virtual void start(const std::vector<Mover>& segments, const exec::Coordinator& c) = 0;
  virtual void stop(int entity) = 0;
  /// One control cycle: the segments that ended in it.
  virtual std::vector<SegmentEnd> cycle() = 0;
  virtual double time() const = 0;
  virtual std::vector<Eigen::Vector2d> positions() const = 0;
  /// The positions `entity`'s latest segment passed through.
  virtual exec::Path executed(int entity) const = 0;
  /// A hand puts `entity` down `by` away. Returns whether its follower fails its segment
  /// (it left its path and cannot follow on).
  virtual bool displace(int entity, const Eigen::Vector2d& by) = 0;
  virtual void stall(int entity, double seconds) = 0;
  /// Robot `entity` dies where it is.
  virtual void kill(int entity) = 0;
  /// Robot `entity` moves at `factor` of the speed it is driven at, for the whole run.
  virtual void setSpeedFactor(int entity, double factor) = 0;
  virtual bool bodies() const { return false; }
  virtual exec::BodyReport report() const { return {}; }
};

double traveled(const exec::Path& p) {
  double s = 0;
  for (size_t i = 1; i < p.size(); ++i) s += (p[i] - p[i - 1]).norm();
  return s;
}

/// Points: every entity follows its segment's path ideally at cruise speed; a pushed
/// entity fails its segment. A load its carrier carries in their step (exec::carries)
/// moves along its own path only while the carrier moves: it stands while its carrier is
/// stalled or dead, as a riding or pushed load does on a table with bodies.
class PointTable : public Table {
 public:
  PointTable(const task::TaskSpec& spec, std::vector<Eigen::Vector2d> start) : spec_(spec), pos_(std::move(start)) {}
  void start(const std::vector<Mover>& segments, const exec::Coordinator&) override {
    for (const Mover& s : segments) {
      stop(s.entity);
      Running r;
      r.mover = s;
      r.executed = {pos_[static_cast<size_t>(s.entity)]};
      running_.push_back(std::move(r));
    }
  }
  void stop(int e) override {
    for (auto it = running_.begin(); it != running_.end();)
      if (it->mover.entity == e) {
        executed_[e] = it->executed;
        it = running_.erase(it);
      } else {
        ++it;
      }
  }
  std::vector<SegmentEnd> cycle() override {
    now_ += kCycleS;
    std::vector<SegmentEnd> out;
    for (Running& r : running_) {
      if (standing(r) || standingCarrier(r)) continue;
      const auto f = factor_.find(r.mover.entity);
      r.along = std::min(r.mover.length, r.along + speed_ * (f == factor_.end() ? 1.0 : f->second) * kCycleS);
      pos_[static_cast<size_t>(r.mover.entity)] = pointAt(r.mover.path, r.along);
      r.executed.push_back(pos_[static_cast<size_t>(r.mover.entity)]);
      if (r.along >= r.mover.length) out.push_back({r.mover.entity, r.mover.segment, true, ""});
    }
    return out;
  }
  double time() const override { return now_; }
  std::vector<Eigen::Vector2d> positions() const override { return pos_; }
  exec::Path executed(int e) const override {
    for (const Running& r : running_)
      if (r.mover.entity == e) return r.executed;
    const auto it = executed_.find(e);
    return it == executed_.end() ? exec::Path{} : it->second;
  }
  bool displace(int e, const Eigen::Vector2d& by) override {
    pos_[static_cast<size_t>(e)] += by;
    return true;
  }
  void stall(int e, double seconds) override {
    for (Running& r : running_)
      if (r.mover.entity == e) r.stalled_until_s = now_ + seconds;
  }
  void kill(int e) override {
    for (Running& r : running_)
      if (r.mover.entity == e) r.lost = true;
  }
  void setSpeedFactor(int e, double factor) override { factor_[e] = factor; }

 private:
  struct Running {
    Mover mover;
    exec::Path executed;
    double along = 0, stalled_until_s = -1;
    bool lost = false;
  };
  bool standing(const Running& r) const { return r.lost || now_ < r.stalled_until_s; }
  /// Whether `load` is carried in its step by a robot segment that stands now.
  bool standingCarrier(const Running& load) const {
    return std::any_of(running_.begin(), running_.end(), [&](const Running& c) {
      return &c != &load && standing(c) &&
             exec::carries(spec_, c.mover.step, c.mover.token, load.mover.step, load.mover.token);
    });
  }
  const task::TaskSpec& spec_;
  std::vector<Eigen::Vector2d> pos_;
  std::vector<Running> running_;
  std::map<int, exec::Path> executed_;
  std::map<int, double> factor_;  ///< per entity: its speed factor (absent: 1)
  double now_ = 0;
  const double speed_ = exec::FollowerGains{}.cruise_speed_mps;
};

/// Bodies: the robots' own control cycles on the simulated table (exec::BodiesExecution),
/// segments starting whenever the coordinator sends them.
class BodyTable : public Table {
 public:
  BodyTable(const exec::BodiesExecutionParams& params, const task::TaskSpec& spec, const task::Demonstration& gt)
      : spec_(spec), execution_(params) {
    execution_.beginTrial(spec, exec::startPoses(gt));
  }
  void start(const std::vector<Mover>& segments, const exec::Coordinator& c) override {
    std::map<int, std::vector<const Mover*>> by_step;
    for (const Mover& s : segments) by_step[s.step].push_back(&s);
    for (const auto& [step, movers] : by_step) {
      std::vector<task::Token> tokens;
      for (const exec::TokenRecord& t : c.steps().at(static_cast<size_t>(step)).tokens) tokens.push_back(t.token);
      std::vector<exec::StepMotion> motions;
      for (const Mover* m : movers) {
        const auto at = std::find_if(tokens.begin(), tokens.end(),
                                     [&](const task::Token& t) { return t.entity == m->entity && t == m->token; });
        motions.push_back({static_cast<size_t>(at - tokens.begin()), m->entity, m->token.target,
                           spec_.entities[static_cast<size_t>(m->entity)].kind == task::EntityKind::Robot, m->path});
        segment_[m->entity] = m->segment;
      }
      const std::vector<std::string> failures = execution_.startMotions(spec_, step, tokens, motions);
      size_t f = 0;
      for (const Mover* m : movers)
        if (!execution_.moving(m->entity))
          pending_.push_back({m->entity, m->segment, false, f < failures.size() ? failures[f++] : "not started"});
    }
  }
  void stop(int e) override { execution_.stopMotion(e); }
  std::vector<SegmentEnd> cycle() override {
    std::vector<SegmentEnd> out;
    out.swap(pending_);
    for (const exec::MotionEnd& e : execution_.cycle())
      out.push_back({e.entity, segment_[e.entity], e.done, e.message});
    return out;
  }
  double time() const override { return execution_.time(); }
  std::vector<Eigen::Vector2d> positions() const override { return execution_.positions(); }
  exec::Path executed(int e) const override { return execution_.executed(e); }
  bool displace(int e, const Eigen::Vector2d& by) override {
    execution_.displace(e, by);
    return false;  // its controller follows on from where it is
  }
  void stall(int e, double seconds) override { execution_.stall(e, execution_.time() + seconds); }
  void kill(int e) override { execution_.kill(e); }
  void setSpeedFactor(int e, double factor) override { execution_.setSpeedFactor(e, factor); }
  bool bodies() const override { return true; }
  exec::BodyReport report() const override { return execution_.report(); }

 private:
  const task::TaskSpec& spec_;
  exec::BodiesExecution execution_;
  std::map<int, uint32_t> segment_;  ///< per entity: its latest segment
  std::vector<SegmentEnd> pending_;  ///< could not start: reported at the next cycle
};

/// The moment of the perturbation: a step of the demonstration, how far along a motion
/// of it (or of a later step) is, and a direction.
struct Draw {
  int step = 0;
  double fraction = 0.5;
  double angle = 0;
};

class Runner {
 public:
  Runner(const Model& model, const task::TaskSpec& spec, const task::Demonstration& gt, const Perturbation& p,
         int max_replans, exec::DispatchMode dispatch, uint64_t seed, const exec::BodiesExecutionParams* bodies,
         double speed_spread)
      : model_(model),
        spec_(spec),
        gt_(gt),
        p_(p),
        c_(spec, config(spec, max_replans, dispatch, !bodies || bodies->config.table.loads_ride),
           model.primitives->endPoints(), 1, model.sequence.info().dependencies, policyReadsScene(model)) {
    for (const exec::Pose2D& pose : exec::startPoses(gt)) pos_.push_back(pose.position());
    tracked_.assign(pos_.size(), true);
    if (bodies) table_ = std::make_unique<BodyTable>(*bodies, spec, gt);
    else table_ = std::make_unique<PointTable>(spec, pos_);
    SplitMix64 rng(seed * 0x2545F4914F6CDD1DULL + 0x5eed);
    // A step of the demonstration with a motion the kind fits.
    std::vector<int> steps;
    for (size_t k = 0; k < gt.steps.size(); ++k)
      if (std::any_of(gt.steps[k].tokens.begin(), gt.steps[k].tokens.end(),
                      [&](const task::Token& t) { return t.isMotion() && fitsKind(t); }))
        steps.push_back(static_cast<int>(k));
    draw_.step = steps.empty() ? 0 : steps[rng.index(steps.size())];
    draw_.fraction = rng.uniform(0.2, 0.8);
    draw_.angle = rng.uniform(0, 2 * M_PI);
    // Robots that differ in speed: a stream of its own, so the same trial seed draws the
    // same perturbation with or without it, and the same speeds under either dispatch.
    SplitMix64 speeds(seed * 0x9E3779B97F4A7C15ULL + 0x5bd);
    if (speed_spread > 0)
      for (size_t e = 0; e < spec.entities.size(); ++e)
        if (spec.entities[e].kind == task::EntityKind::Robot)
          table_->setSpeedFactor(static_cast<int>(e), 1 - speed_spread * speeds.uniform(0, 1));
  }

  CoordinatedRun run() {
    handle(c_.onEntities({pos_, tracked_}, now_));
    handle(c_.start(now_));
    while (c_.running() && now_ < kMaxRunS) cycle();
    return result();
  }

 private:
  /// `loads_ride`: the table's (points: every carrier stays where its path ends).
  static exec::CoordinatorConfig config(const task::TaskSpec& spec, int max_replans, exec::DispatchMode dispatch,
                                        bool loads_ride) {
    exec::CoordinatorConfig cfg;
    cfg.loads_ride = loads_ride;
    cfg.arrival_radius_m = spec.arrival_radius;
    cfg.max_replans = max_replans;
    cfg.dispatch = dispatch;
    return cfg;
  }

  /// Answers what the coordinator asks for at once (decisions and paths take no time).
  void handle(exec::CoordinatorOutput first) {
    std::deque<exec::CoordinatorOutput> pending{std::move(first)};
    while (!pending.empty()) {
      const exec::CoordinatorOutput out = std::move(pending.front());
      pending.pop_front();
      for (int e : out.stop) {
        drop(e);
        table_->stop(e);
      }
      std::vector<Mover> started;
      for (const exec::SegmentCommand& s : out.segments) {
        drop(s.entity);
        Mover m;
        m.entity = s.entity, m.segment = s.segment_id, m.step = s.step, m.token = s.token;
        m.path = s.path.points.empty() ? exec::Path{s.goal} : s.path.points;
        m.length = lengthOf(m.path);
        started.push_back(m);
        movers_.push_back(std::move(m));
      }
      if (!started.empty()) table_->start(started, c_);
      for (const exec::PathRequest& r : out.paths) {
        try {
          const gp::GeneratedPath g = model_.primitives->generate(r.token, r.start, r.goal, 100, r.step);
          pending.push_back(c_.onPath(r.id, {g.points, g.stddev}, "", now_));
        } catch (const Error& e) {
          pending.push_back(c_.onPath(r.id, {}, e.what(), now_));
        }
      }
      if (out.decision) {
        try {
          pending.push_back(c_.onDecision(out.decision->id, decide(*out.decision), now_));
        } catch (const Error& e) {
          pending.push_back(c_.onDecisionError(out.decision->id, e.what(), now_));
        }
      }
    }
  }

  /// The policy's answer to `request`: with robots lost, for the team without them
  /// (DecisionsWithout). Throws ddace::Error when the model cannot decide without them.
  exec::Decision decide(const exec::DecisionRequest& request) {
    lost_entities_ = request.lost;
    const tgn::Prediction d = decisions_.predict(request.history, request.lost);
    return {d.end, d.tokens};
  }

  /// `e`'s segment is over (stopped, replaced or done): what it ran is kept.
  void drop(int e) {
    for (auto it = movers_.begin(); it != movers_.end();)
      if (it->entity == e) {
        executed_[it->segment] = table_->executed(e);
        it = movers_.erase(it);
      } else {
        ++it;
      }
  }

  void cycle() {
    const std::vector<SegmentEnd> ended = table_->cycle();
    now_ = table_->time();
    pos_ = table_->positions();
    const std::optional<std::pair<int, uint32_t>> failed = perturb();
    handle(c_.onEntities({pos_, tracked_}, now_));
    if (failed) {
      drop(failed->first);
      handle(c_.onSegmentStatus(failed->first, failed->second, exec::SegmentState::Failed, 0.5, "pushed off its path",
                                now_));
    }
    for (const SegmentEnd& e : ended) {
      if (std::none_of(movers_.begin(), movers_.end(), [&](const Mover& m) { return m.segment == e.segment; }))
        continue;
      drop(e.entity);
      handle(c_.onSegmentStatus(e.entity, e.segment, e.done ? exec::SegmentState::Done : exec::SegmentState::Failed,
                                e.done ? 1.0 : 0.5, e.message, now_));
      if (e.done) countStaleEnd(e.segment);
    }
    handle(c_.onTick(now_));
  }

  /// How far along its path `m`'s entity has come (metres).
  double along(const Mover& m) const { return std::min(m.length, traveled(table_->executed(m.entity))); }

  /// box_moved: a motion toward a box; the others: a robot's motion.
  bool fitsKind(const task::Token& t) const {
    const auto kind = [&](int e) { return spec_.entities[static_cast<size_t>(e)].kind; };
    if (p_.kind == PerturbationKind::BoxMoved) return t.target >= 0 && kind(t.target) == task::EntityKind::Object;
    return kind(t.entity) == task::EntityKind::Robot;
  }

  bool fits(const Mover& m) const {
    if (m.step < draw_.step || m.length < 1e-6 || !fitsKind(m.token)) return false;
    if (const double a = along(m); a < draw_.fraction * m.length || a >= m.length) return false;
    // A box that a motion of the run moves is not put down by a hand.
    return p_.kind != PerturbationKind::BoxMoved ||
           std::none_of(movers_.begin(), movers_.end(), [&](const Mover& o) { return o.entity == m.token.target; });
  }

  /// How far a hand moves `e` (amount metres): along the first of `directions` where it
  /// lands clear of every other body by kLandingGapM (a hand puts a thing down where it
  /// fits, it does not shove it into another), else the first.
  Eigen::Vector2d landing(int e, const std::vector<Eigen::Vector2d>& directions) const {
    for (const Eigen::Vector2d& d : directions) {
      const Eigen::Vector2d at = pos_[static_cast<size_t>(e)] + p_.amount * d;
      bool clear = true;
      for (int j = 0; j < static_cast<int>(pos_.size()); ++j)
        if (j != e && spec_.entities[static_cast<size_t>(j)].kind != task::EntityKind::Goal &&
            (at - pos_[static_cast<size_t>(j)]).norm() < spec_.contactDistance(e, j) + kLandingGapM)
          clear = false;
      if (clear) return p_.amount * d;
    }
    return p_.amount * directions.front();
  }

  /// Applies the perturbation when its moment has come; returns a segment its follower fails.
  std::optional<std::pair<int, uint32_t>> perturb() {
    if (applied_ || p_.kind == PerturbationKind::None) return std::nullopt;
    const auto m = std::find_if(movers_.begin(), movers_.end(), [&](const Mover& o) { return fits(o); });
    if (m == movers_.end()) return std::nullopt;
    applied_ = true;
    char what[200];
    const double at = along(*m);
    const int pct = static_cast<int>(std::lround(100 * at / m->length));
    const auto name = [&](int e) { return spec_.entities[static_cast<size_t>(e)].name.c_str(); };
    std::optional<std::pair<int, uint32_t>> failed;
    switch (p_.kind) {
      case PerturbationKind::BoxMoved: {
        std::vector<Eigen::Vector2d> directions;
        for (int k = 0; k < 8; ++k)
          directions.emplace_back(std::cos(draw_.angle + k * M_PI / 4), std::sin(draw_.angle + k * M_PI / 4));
        table_->displace(m->token.target, landing(m->token.target, directions));
        std::snprintf(what, sizeof what, "step %d, %d %%: %s moved %.1f cm", m->step + 1, pct, name(m->token.target),
                      p_.amount * 100);
        break;
      }
      case PerturbationKind::RobotPushed: {
        const Eigen::Vector2d ahead = pointAt(m->path, std::min(m->length, at + 0.01)) - pos_[m->entity];
        const Eigen::Vector2d across =
            ahead.norm() > 1e-9 ? Eigen::Vector2d(-ahead.y(), ahead.x()).normalized() : Eigen::Vector2d(1, 0);
        if (table_->displace(m->entity, landing(m->entity, {across, -across})))
          failed = std::make_pair(m->entity, m->segment);
        std::snprintf(what, sizeof what, "step %d, %d %%: %s pushed %.1f cm off its path", m->step + 1, pct,
                      name(m->entity), p_.amount * 100);
        break;
      }
      case PerturbationKind::RobotStalled:
        table_->stall(m->entity, p_.amount);
        std::snprintf(what, sizeof what, "step %d, %d %%: %s stalled %.1f s", m->step + 1, pct, name(m->entity),
                      p_.amount);
        break;
      case PerturbationKind::RobotLost:
        table_->kill(m->entity);
        lost_robot_ = m->entity;
        tracked_[static_cast<size_t>(m->entity)] = false;
        std::snprintf(what, sizeof what, "step %d, %d %%: %s lost", m->step + 1, pct, name(m->entity));
        break;
      case PerturbationKind::None:
        break;
    }
    what_ = what;
    pos_ = table_->positions();
    scene_after_ = pos_;
    perturbed_step_ = m->step;
    return failed;
  }

  /// A motion that ended where its target had left (by a hand: not moved by a token of
  /// its own step) did not do its step.
  void countStaleEnd(uint32_t segment) {
    for (const exec::StepRecord& s : c_.steps())
      for (const exec::TokenRecord& t : s.tokens) {
        if (t.segment_id != segment || t.state != exec::SegmentState::Done || t.token.target < 0) continue;
        const bool moved_by_step = std::any_of(s.tokens.begin(), s.tokens.end(), [&](const exec::TokenRecord& o) {
          return o.token.entity == t.token.target && o.token.isMotion();
        });
        const double left = (pos_[static_cast<size_t>(t.token.target)] - t.target_start).norm();
        if (!moved_by_step && left > spec_.arrival_radius + exec::CoordinatorConfig{}.arrival_tolerance_m)
          ++stale_ends_;
      }
  }

  /// Why a finished run does not score as a success: the first step that differs, else
  /// what of the motions or goal conditions did not hold.
  std::string failureOf(const eval::TrialScore& score, const exec::Trial& t) const {
    const auto keys = [&](const std::vector<task::Step>& steps, size_t k) {
      if (k >= steps.size()) return std::string("{END}");
      std::vector<task::Token> tokens = steps[k].tokens;
      std::sort(tokens.begin(), tokens.end());
      std::string out;
      for (const task::Token& tok : tokens) out += (out.empty() ? "" : " ") + task::tokenKey(tok, spec_);
      return "{" + out + "}";
    };
    for (size_t k = 0; k < std::max(gt_.steps.size(), t.predicted.size()); ++k)
      if (keys(t.predicted, k) != keys(gt_.steps, k))
        return "step " + std::to_string(k + 1) + ": predicted " + keys(t.predicted, k) + " demonstrated " +
               keys(gt_.steps, k);
    if (score.achieved_robot_motions < score.gt_robot_motions) return "a robot motion stopped short of its end point";
    if (!t.body_report.collisions.empty()) return collisions(t);
    if (!score.objectsArrived()) return score.objects_left_short.front().describe();
    return "a goal condition does not hold";
  }

  /// "2 collision(s), the first at 3.1 s: R1 touched R2".
  std::string collisions(const exec::Trial& t) const {
    const exec::BodyContact& c = t.body_report.collisions.front();
    char what[160];
    std::snprintf(what, sizeof what, "%zu collision(s), the first at %.1f s: %s touched %s",
                  t.body_report.collisions.size(), c.time_s, spec_.entities[static_cast<size_t>(c.a)].name.c_str(),
                  spec_.entities[static_cast<size_t>(c.b)].name.c_str());
    return what;
  }

  /// Why a run that finished without its lost robots did not do the task ("" when it did):
  /// a robot motion that stopped short of its end point, a collision, a goal condition
  /// that does not name a lost robot and does not hold.
  std::string withoutLost(const exec::Trial& t) const { return taskUndone(t, gt_); }

  /// Why finished run `t` did not do the task ("" when it did), the steps of `ends` stating
  /// where objects end when the task states no goal condition (withoutLost); `ends_by`
  /// names whose steps they are.
  std::string taskUndone(const exec::Trial& t, const task::Demonstration& ends,
                         const std::string& ends_by = "the demonstration") const {
    const double within = spec_.arrival_radius + exec::CoordinatorConfig{}.arrival_tolerance_m;
    for (const exec::ExecutedToken& ex : t.executed)
      if (ex.token.isMotion() && spec_.entities[static_cast<size_t>(ex.token.entity)].kind == task::EntityKind::Robot &&
          !task::arrived(ex.executed.back(), ex.goal, within))
        return "step " + std::to_string(ex.step + 1) + ": " + task::tokenKey(ex.token, spec_) +
               " stopped short of its end point";
    if (!t.body_report.collisions.empty()) return collisions(t);
    const std::vector<int>& lost = lost_entities_;
    for (const task::GoalCondition& g : spec_.goal_conditions) {
      const bool names_lost = std::any_of(lost.begin(), lost.end(), [&](int e) {
        return spec_.entities[static_cast<size_t>(e)].name == g.entity ||
               spec_.entities[static_cast<size_t>(e)].name == g.at;
      });
      if (!names_lost && !task::goalConditionMet(spec_, g, t.final_positions))
        return "goal condition " + g.entity + " at " + g.at + " does not hold";
    }
    if (spec_.goal_conditions.empty()) return objectNotWhereDemonstrated(spec_, ends, t.final_positions, lost, ends_by);
    return "";
  }

  /// A zoo task: a box moved under its first step, or a robot lost for good. The rule's
  /// steps on the scene right after the hand or the loss, for the team left, are the
  /// measure; the demonstration is of the scene before it and of the whole team. Where the
  /// rule needs more robots than are left, see judgeTooFewLeft.
  void judgeByRule(CoordinatedRun& r) const {
    uint64_t id = 0;
    tasks::ZooMotion motion;
    const bool moved = p_.kind == PerturbationKind::BoxMoved && perturbed_step_ == 0;
    const bool lost = p_.kind == PerturbationKind::RobotLost;
    if (!applied_ || !(moved || lost) || !tasks::zooRuleOfTask(spec_, id, motion)) return;
    const std::vector<int> without = lost ? std::vector<int>{lost_robot_} : std::vector<int>{};
    tasks::ZooNoAnswer no_answer = tasks::ZooNoAnswer::NearTie;
    task::Demonstration rule;
    if (const auto steps = tasks::zooSteps(id, spec_, scene_after_, motion, without, &no_answer)) rule.steps = *steps;
    else if (no_answer == tasks::ZooNoAnswer::NearTie) return void(r.rule_tie = true);  // no one answer there
    else return judgeTooFewLeft(r);
    const exec::Trial& t = r.trial;
    std::string why = r.finished ? "" : "not finished: " + r.reason;
    // Steps are compared under the first step only: after a loss the run's record holds
    // the steps before it and those decided again (from the first, for a carrier lost with
    // its load), where the rule restarts from the scene at the loss; its ends are the measure.
    for (size_t k = 0; moved && k < std::max(rule.steps.size(), t.predicted.size()) && why.empty(); ++k) {
      std::vector<task::Token> a = k < t.predicted.size() ? t.predicted[k].tokens : std::vector<task::Token>{};
      std::vector<task::Token> b = k < rule.steps.size() ? rule.steps[k].tokens : std::vector<task::Token>{};
      std::sort(a.begin(), a.end()), std::sort(b.begin(), b.end());
      if (a != b) why = "step " + std::to_string(k + 1) + " is not the rule's on the scene after the hand";
    }
    if (why.empty()) why = taskUndone(t, rule, "the rule");
    if (why.empty() && stale_ends_ > 0) why = "a motion ended where its target had left";
    r.by_rule = why.empty();
    r.rule_failure = why;
  }

  /// The rule needs more robots than are left, so it states nothing for the team left: done
  /// by aborting naming the lost robot, or by a run that ends with the task's own end (every
  /// object where the demonstration left it: the team left did it another way).
  void judgeTooFewLeft(CoordinatedRun& r) const {
    if (abortedNamingLost(r)) return void(r.by_rule = 1);
    std::string undone = r.finished ? withoutLost(r.trial) : "aborted without naming it: " + r.reason;
    if (undone.empty() && stale_ends_ > 0) undone = "a motion ended where its target had left";
    r.by_rule = undone.empty();
    if (!undone.empty())
      r.rule_failure = "the rule needs more robots than are left without " +
                       spec_.entities[static_cast<size_t>(lost_robot_)].name + "; " + undone;
  }

  /// The makespan of the run's steps under async were each token to take the time it took
  /// here (0 when a token did not end).
  double asyncBound(const exec::Dispatch& d) const {
    std::vector<std::vector<task::Token>> steps;
    std::vector<std::vector<double>> durations;
    for (int k = 0; k < d.steps(); ++k) {
      steps.push_back(d.tokens(k));
      durations.emplace_back();
      for (int i = 0; i < static_cast<int>(d.tokens(k).size()); ++i) {
        if (!d.ended({k, i})) return 0;
        durations.back().push_back(d.endTime({k, i}) - d.startTime({k, i}));
      }
    }
    return exec::scheduleSteps(spec_, model_.sequence.info().dependencies, exec::DispatchMode::Async,
                               policyReadsScene(model_), steps, durations, nullptr)
        .makespan();
  }

  CoordinatedRun result() {
    CoordinatedRun r;
    if (c_.running()) handle(c_.abortRun("not ended within " + std::to_string(kMaxRunS) + " s", now_));
    for (const Mover& m : movers_) executed_[m.segment] = table_->executed(m.entity);
    exec::Trial& t = r.trial;
    for (const exec::StepRecord& s : c_.steps()) {
      task::Step step;
      for (const exec::TokenRecord& k : s.tokens) {
        step.tokens.push_back(k.token);
        exec::ExecutedToken ex;
        ex.token = k.token, ex.step = s.step, ex.start = k.start, ex.goal = k.goal, ex.planned = k.path.points;
        const auto run = executed_.find(k.segment_id);
        ex.executed = k.segment_id != 0 && run != executed_.end() ? run->second : exec::Path{k.start};
        if (ex.executed.empty()) ex.executed = {k.start};
        t.executed.push_back(std::move(ex));
      }
      t.predicted.push_back(std::move(step));
    }
    t.ended = c_.state() == exec::RunState::Finished;
    t.final_positions = pos_;
    t.bodies = table_->bodies();
    t.body_report = table_->report();
    if (c_.dispatch()) {
      r.async_bound_s = asyncBound(*c_.dispatch());
      t.makespan_s = c_.dispatch()->makespan();
      r.precedence_violations = c_.dispatch()->violations();
      r.waits = describeWaits(*c_.dispatch(), spec_);
    }
    r.score = eval::scoreTrial(spec_, gt_, t, false);
    r.collisions = r.score.collisions;
    r.perturbed = applied_;
    r.what = what_;
    r.finished = t.ended;
    r.reason = c_.reason();
    r.lost = c_.lostRobots();
    r.stale_ends = stale_ends_;
    r.replans = c_.replans();
    r.redecisions = c_.redecisions();
    r.makespan_s = t.makespan_s;
    r.success = r.finished && r.score.success && stale_ends_ == 0;
    if (r.finished && !r.score.success) r.failure = failureOf(r.score, t);
    judgeByRule(r);
    if (r.finished && !r.lost.empty()) {
      // The team changed: the demonstration's steps are not the measure; the rule's for the
      // team left are where the task states one (judgeByRule), else the task's ends.
      r.failure = r.by_rule >= 0 ? r.rule_failure : withoutLost(t);
      r.success = r.failure.empty() && stale_ends_ == 0;
    }
    return r;
  }

  const Model& model_;
  const task::TaskSpec& spec_;
  const task::Demonstration& gt_;
  Perturbation p_;
  exec::Coordinator c_;
  std::unique_ptr<Table> table_;
  DecisionsWithout decisions_{model_.sequence};
  std::vector<int> lost_entities_;  ///< the robots the last decision was made without
  std::vector<Eigen::Vector2d> pos_;
  std::vector<bool> tracked_;
  std::vector<Mover> movers_;
  std::map<uint32_t, exec::Path> executed_;  ///< by segment id
  Draw draw_;
  double now_ = 0;
  bool applied_ = false;
  std::vector<Eigen::Vector2d> scene_after_;  ///< every entity right after the hand
  int perturbed_step_ = -1;                   ///< the step of the motion it came under
  int lost_robot_ = -1;                       ///< robot_lost: the robot that died
  std::string what_;
  int stale_ends_ = 0;
};

struct KindName {
  PerturbationKind kind;
  const char* name;
  double default_amount;  ///< in the unit the text takes (cm, s)
  const char* unit;
};
const KindName kKinds[] = {{PerturbationKind::BoxMoved, "box_moved", 6, "cm"},
                           {PerturbationKind::RobotPushed, "robot_pushed", 5, "cm"},
                           {PerturbationKind::RobotStalled, "robot_stalled", 5, "s"},
                           {PerturbationKind::RobotLost, "robot_lost", 0, ""}};

}  // namespace

std::string objectNotWhereDemonstrated(const task::TaskSpec& spec, const task::Demonstration& gt,
                                       const std::vector<Eigen::Vector2d>& final_positions,
                                       const std::vector<int>& lost, const std::string& whose) {
  std::vector<int> last_target(spec.entities.size(), -1);
  for (const task::Step& s : gt.steps)
    for (const task::Token& k : s.tokens)
      if (k.isMotion()) last_target[static_cast<size_t>(k.entity)] = k.target;
  for (size_t e = 0; e < spec.entities.size(); ++e) {
    const int to = last_target[e];
    const bool to_lost = std::find(lost.begin(), lost.end(), to) != lost.end();
    if (spec.entities[e].kind == task::EntityKind::Robot || to < 0 || to_lost) continue;
    const task::GoalCondition demonstrated{spec.entities[e].name, spec.entities[static_cast<size_t>(to)].name};
    if (!task::goalConditionMet(spec, demonstrated, final_positions))
      return spec.entities[e].name + " did not end at " + demonstrated.at + ", where " + whose + " left it";
  }
  return "";
}

Perturbation parsePerturbation(const std::string& text, const std::string& what) {
  const size_t colon = text.find(':');
  const std::string name = text.substr(0, colon);
  for (const KindName& k : kKinds) {
    if (name != k.name) continue;
    double amount = k.default_amount;
    if (colon != std::string::npos) {
      const std::string number = text.substr(colon + 1);
      size_t used = 0;
      try {
        amount = std::stod(number, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (k.kind == PerturbationKind::RobotLost || used == 0 || used != number.size() || !std::isfinite(amount) ||
          amount <= 0)
        throw Error(what + " '" + text + "': " +
                    (k.kind == PerturbationKind::RobotLost
                         ? std::string("robot_lost takes no amount")
                         : "the amount must be a positive number of " + std::string(k.unit)));
    }
    return {k.kind, std::string(k.unit) == "cm" ? amount / 100 : amount};
  }
  throw Error(what + " '" + text + "' is not one of box_moved[:CM], robot_pushed[:CM], robot_stalled[:S], robot_lost");
}

std::string toString(const Perturbation& p) {
  char s[80];
  for (const KindName& k : kKinds)
    if (k.kind == p.kind) {
      if (std::string(k.unit) == "cm") std::snprintf(s, sizeof s, "%s %.1f cm", k.name, p.amount * 100);
      else if (std::string(k.unit) == "s") std::snprintf(s, sizeof s, "%s %.1f s", k.name, p.amount);
      else std::snprintf(s, sizeof s, "%s", k.name);
      return s;
    }
  return "none";
}

CoordinatedRun runCoordinated(const Model& model, const task::TaskSpec& spec, const task::Demonstration& gt,
                              const Perturbation& p, int max_replans, exec::DispatchMode dispatch, uint64_t seed,
                              const exec::BodiesExecutionParams* bodies, double speed_spread) {
  if (!(speed_spread >= 0 && speed_spread < 1))
    throw Error("speed spread must be in [0, 1): each robot moves at a factor in [1 - spread, 1]");
  if (!model.primitives)
    throw Error("a perturbed run needs a model with primitives (the " + model.sequence.variant() +
                " variant rolls out its own trajectories)");
  return Runner(model, spec, gt, p, max_replans, dispatch, seed, bodies, speed_spread).run();
}

PerturbationReport evaluatePerturbed(const Model& model, const task::TaskDir& test, const Perturbation& p,
                                     exec::DispatchMode dispatch, uint64_t seed,
                                     const exec::BodiesExecutionParams* bodies) {
  PerturbationReport r;
  r.task = model.sequence.spec().name;
  r.variant = model.sequence.variant();
  r.dispatch = exec::toString(dispatch);
  r.perturbation = p;
  for (size_t i = 0; i < test.demos.size(); ++i) {
    const task::Demonstration& gt = test.demos[i];
    const uint64_t s = seed * 1000003ULL + i;
    r.demos.push_back(std::filesystem::path(gt.source).filename().string());
    const int recoveries = exec::CoordinatorConfig{}.max_replans;
    r.unperturbed.push_back(runCoordinated(model, test.spec, gt, {}, recoveries, dispatch, s, bodies));
    r.without.push_back(runCoordinated(model, test.spec, gt, p, 0, dispatch, s, bodies));
    r.with.push_back(runCoordinated(model, test.spec, gt, p, recoveries, dispatch, s, bodies));
  }
  return r;
}

namespace {
struct Totals {
  int perturbed = 0, succeeded = 0, replans = 0, redecisions = 0, violations = 0, collisions = 0;
  int aborted_naming_lost = 0;
  /// Runs judged by the zoo's rule (CoordinatedRun::by_rule), done as it says; of those,
  /// done only by the rule's measure, or only by the demonstration's.
  int by_rule_judged = 0, by_rule_done = 0, by_rule_only = 0, by_demo_only = 0, rule_ties = 0;
  double lost_s = 0;
  int lost_n = 0;
  double makespan_s = 0;  ///< mean over the runs counted
};
/// Over the perturbed trials (`all`: over every trial, the unperturbed runs).
Totals totals(const PerturbationReport& r, const std::vector<CoordinatedRun>& runs, bool all = false) {
  Totals t;
  for (size_t i = 0; i < runs.size(); ++i) {
    const CoordinatedRun& u = r.unperturbed[i];
    t.violations += runs[i].precedence_violations;
    if (!all && !r.with[i].perturbed) continue;
    ++t.perturbed;
    t.succeeded += runs[i].success;
    t.aborted_naming_lost += abortedNamingLost(runs[i]);
    t.rule_ties += runs[i].rule_tie;
    if (runs[i].by_rule >= 0) {
      ++t.by_rule_judged;
      t.by_rule_done += runs[i].by_rule;
      t.by_rule_only += runs[i].by_rule && !runs[i].success;
      t.by_demo_only += !runs[i].by_rule && runs[i].success;
    }
    t.makespan_s += runs[i].makespan_s;
    t.replans += runs[i].replans;
    t.redecisions += runs[i].redecisions;
    t.collisions += runs[i].collisions;
    if (runs[i].success && u.success) t.lost_s += runs[i].makespan_s - u.makespan_s, ++t.lost_n;
  }
  const int counted = all ? static_cast<int>(runs.size()) : t.perturbed;
  if (counted > 0) t.makespan_s /= counted;
  return t;
}
/// Where the zoo's rule judges a run from (Runner::judgeByRule).
const char* ruleScene(const Perturbation& p) {
  return p.kind == PerturbationKind::RobotLost ? "for the team left, on the scene at the loss"
                                               : "on the scene after the hand";
}
std::string outcome(const CoordinatedRun& run) {
  char s[64];
  std::snprintf(s, sizeof s, "%s %.1f s", run.success ? "yes" : "no ", run.makespan_s);
  return s;
}
}  // namespace

void printPerturbation(const PerturbationReport& r, std::ostream& out) {
  char line[512];
  std::snprintf(line, sizeof line, "%-16s %-12s %-17s %-14s %s\n", "trial", "unperturbed", "without recovery",
                "with recovery", "perturbation");
  out << line;
  for (size_t i = 0; i < r.demos.size(); ++i) {
    const CoordinatedRun &u = r.unperturbed[i], &wo = r.without[i], &w = r.with[i];
    std::snprintf(line, sizeof line, "%-16s %-12s %-17s %-14s %s\n", r.demos[i].c_str(), outcome(u).c_str(),
                  outcome(wo).c_str(), outcome(w).c_str(), w.perturbed ? w.what.c_str() : "(no motion fits it)");
    out << line;
    for (const CoordinatedRun* run : {&wo, &w}) {
      const char* which = run == &wo ? "without" : "with";
      if (!run->success && !run->reason.empty() && !run->finished)
        out << "    " << which << ": " << run->reason << "\n";
      if (!run->failure.empty()) out << "    " << which << ": " << run->failure << "\n";
      if (run->stale_ends > 0)
        out << "    " << which << ": " << run->stale_ends << " motion(s) ended where their target had left\n";
    }
    if (w.by_rule >= 0 || w.rule_tie)
      out << "    with, by the rule " << ruleScene(r.perturbation) << ": "
          << (w.rule_tie  ? "a near tie there, not judged"
              : w.by_rule ? "done"
                          : w.rule_failure)
          << "\n";
    for (const std::string& l : w.lost) out << "    with: lost for good: " << l << "\n";
    if (w.replans + w.redecisions > 0)
      out << "    with: " << w.replans << " re-plan(s), " << w.redecisions << " re-decision(s)\n";
  }
  const Totals u = totals(r, r.unperturbed, true), wo = totals(r, r.without), w = totals(r, r.with);
  std::snprintf(line, sizeof line,
                "%s, variant %s, dispatch %s, perturbation %s: %zu trials, %d perturbed\n"
                "  unperturbed:      %d/%zu succeeded, mean makespan %.2f s\n"
                "  without recovery: %d/%d perturbed succeeded\n"
                "  with recovery:    %d/%d perturbed succeeded, %d re-plans, %d re-decisions, time lost %.1f s "
                "(mean of %d)\n"
                "  precedence violations: %d\n",
                r.task.c_str(), r.variant.c_str(), r.dispatch.c_str(), toString(r.perturbation).c_str(), r.demos.size(),
                w.perturbed, u.succeeded, r.demos.size(), u.makespan_s, wo.succeeded, wo.perturbed, w.succeeded,
                w.perturbed, w.replans, w.redecisions, w.lost_n ? w.lost_s / w.lost_n : 0.0, w.lost_n,
                u.violations + wo.violations + w.violations);
  out << line;
  if (r.perturbation.kind == PerturbationKind::RobotLost) {
    std::snprintf(line, sizeof line,
                  "  robot lost, with recovery: %d/%d went on without it and succeeded, %d/%d aborted naming it, "
                  "%d/%d neither\n",
                  w.succeeded, w.perturbed, w.aborted_naming_lost, w.perturbed,
                  w.perturbed - w.succeeded - w.aborted_naming_lost, w.perturbed);
    out << line;
  }
  if (w.by_rule_judged + w.rule_ties > 0) {
    std::snprintf(line, sizeof line,
                  "  with recovery, judged by the zoo's rule %s: %d/%d done as it says "
                  "(of them %d failed against the demonstration; %d not done succeeded against it), %d near "
                  "ties not judged\n",
                  ruleScene(r.perturbation), w.by_rule_done, w.by_rule_judged, w.by_rule_only, w.by_demo_only,
                  w.rule_ties);
    out << line;
  }
  if (!r.unperturbed.empty() && r.unperturbed.front().trial.bodies) {
    std::snprintf(line, sizeof line, "  collisions: %d unperturbed, %d without recovery, %d with\n", u.collisions,
                  wo.collisions, w.collisions);
    out << line;
  }
}

std::string perturbationJson(const PerturbationReport& r) {
  nlohmann::json j;
  j["task"] = r.task;
  j["variant"] = r.variant;
  j["dispatch"] = r.dispatch;
  j["perturbation"] = toString(r.perturbation);
  j["trials"] = r.demos.size();
  const auto runJson = [](const CoordinatedRun& run) {
    return nlohmann::json{{"success", run.success},         {"finished", run.finished},
                          {"reason", run.reason},           {"failure", run.failure},
                          {"stale_ends", run.stale_ends},   {"replans", run.replans},
                          {"redecisions", run.redecisions}, {"makespan_s", run.makespan_s},
                          {"collisions", run.collisions},   {"lost", run.lost},
                          {"by_rule", run.by_rule},         {"rule_failure", run.rule_failure},
                          {"rule_tie", run.rule_tie},       {"precedence_violations", run.precedence_violations}};
  };
  for (const auto& [name, runs] :
       {std::pair<const char*, const std::vector<CoordinatedRun>*>{"unperturbed", &r.unperturbed},
        {"without_recovery", &r.without},
        {"with_recovery", &r.with}}) {
    const Totals t = totals(r, *runs, runs == &r.unperturbed);
    j[name] = {{"perturbed", t.perturbed},
               {"succeeded", t.succeeded},
               {"aborted_naming_lost", t.aborted_naming_lost},
               {"by_rule_judged", t.by_rule_judged},
               {"by_rule_done", t.by_rule_done},
               {"rule_ties", t.rule_ties},
               {"replans", t.replans},
               {"redecisions", t.redecisions},
               {"collisions", t.collisions},
               {"precedence_violations", t.violations}};
  }
  j["per_trial"] = nlohmann::json::array();
  for (size_t i = 0; i < r.demos.size(); ++i)
    j["per_trial"].push_back({{"demo", r.demos[i]},
                              {"perturbation", r.with[i].perturbed ? r.with[i].what : ""},
                              {"unperturbed", runJson(r.unperturbed[i])},
                              {"without_recovery", runJson(r.without[i])},
                              {"with_recovery", runJson(r.with[i])}});
  return j.dump(2) + "\n";
}

}  // namespace ddace::pipeline
