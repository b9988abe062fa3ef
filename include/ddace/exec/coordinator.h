// The coordinator's state machine: the event-driven execution of a learned task.
//
//   Idle --start--> WaitingForEntities --all tracked--> Deciding --step--> Planning
//     --paths--> Executing --tokens end--> ... --END and every token ended--> Finished;
//   any failure / time-out --> Aborted;  e-stop --> EStopped
//
// Each decided token starts when the dispatch rule (exec/dispatch.h) lets it: in `steps`
// when every token of the earlier steps has ended (the paper's execution), in `async` when
// its own predecessors under the learned dependencies have ended. A decision is requested
// when the run starts and then when Dispatch::mayDecide allows it (steps: once every started
// token has ended; async with a policy that does not read the scene: as soon as the last one
// was made; async with one that does: ahead, once every step before the latest has ended,
// from the scene the latest step's tokens will leave, held only if the scene settles as
// predicted): never on a timer. onTick() only checks time-outs.
// When the table changes under a running token the run recovers from the scene as it is
// (CoordinatorConfig::max_replans): the step is re-decided when the policy reads the scene,
// else the token's path is re-planned -- never a pushed load's alone (its carrier moves it):
// its step is re-decided, or the run aborts.
// The goal of a motion token is its end point (task/end_point.h) from the positions when
// it started (the step's tokens that started earlier at their start): at contact with a
// body, on a goal, a carrier behind its load (a pushing one backed off it, exec::carrierEnd). Every motion token, a
// robot's or an object's, becomes one segment for that entity whose path ends there; tokens that start together are
// planned together and their segments go out together; in-place tokens end when they start. The state is the busiest of
// what is under way: Executing while a segment runs, else Planning while a path is awaited, else Deciding.
//
// Owns: the run's state, the requests and segments it sends, the record of what was
// executed. Must not: talk ROS, read clocks (time comes in as `now_s`), plan paths or
// predict steps (those answers come in as events).
// Units: metres, seconds; table frame.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ddace/exec/dispatch.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/simulator.h"
#include "ddace/graph/dependencies.h"
#include "ddace/task/demonstration.h"
#include "ddace/task/end_point.h"
#include "ddace/task/task_spec.h"

namespace ddace::exec {

enum class RunState : uint8_t {
  Idle = 0,                ///< not started (or reset)
  WaitingForEntities = 1,  ///< some entity is not tracked; no decision until all are
  Deciding = 2,            ///< a decision request is out
  Planning = 3,            ///< path requests for the step's motion tokens are out
  Executing = 4,           ///< segments are out; waiting for them to be done
  Paused = 5,              ///< stopped by the user; start() resumes
  Finished = 6,            ///< the policy said END
  Aborted = 7,             ///< failure or time-out; reason() says which
  EStopped = 8,            ///< emergency stop; only reset() leaves it
};
/// "idle", "waiting_for_entities", "deciding", ...
const char* toString(RunState state);

/// What an entity's executor reports about its segment.
enum class SegmentState : uint8_t { Sent = 0, Accepted = 1, Running = 2, Done = 3, Failed = 4, Aborted = 5 };
const char* toString(SegmentState state);

struct CoordinatorConfig {
  double decision_timeout_s = 10;       ///< no decision within this -> abort
  double path_timeout_s = 10;           ///< not every path within this -> abort
  double segment_timeout_s = 30;        ///< base time a segment may take ...
  double segment_timeout_per_m_s = 20;  ///< ... plus this much per metre of path
  int max_steps = 50;                   ///< more decided steps than this -> abort
  /// A DONE counts only when the coordinator's own tracked position of the entity has
  /// arrived (task::arrived) within arrival_radius_m + arrival_tolerance_m of the segment's
  /// end point. The tolerance covers the tracker's noise between the executor's reading
  /// and the coordinator's; executors stop within task::stopRadius(arrival_radius_m,
  /// arrival_tolerance_m): the radius less the same tolerance.
  double arrival_radius_m = task::kDefaultArrivalRadius;
  double arrival_tolerance_m = task::kArrivalToleranceM;
  /// When a decided token starts (exec/dispatch.h). The one default of the coordinator node
  /// (config/execution.yaml states it) and of `ddace eval --dispatch`.
  DispatchMode dispatch = DispatchMode::Steps;
  /// When the table changes under a token -- its segment FAILED or ABORTED (a robot pushed
  /// off its path, blocked), it timed out (stalled), or its target moved more than
  /// arrival_radius_m + arrival_tolerance_m since it started (a box nudged) -- the run
  /// recovers from the scene as it is, at most this many times per token (re-plans) and per
  /// step (re-decisions):
  ///  - re-plan: the step stays, the token's entity is stopped and gets a path from where it
  ///    is to its end point (from where the target is now if it moved);
  ///  - re-decision, when the policy reads the scene (the latest step only): every token of
  ///    the step that has not ended is stopped and withdrawn, and the step is asked for again
  ///    from a snapshot of now in place of the one it was decided from (the policy may decide
  ///    other tokens, or END when the change did the work).
  /// A moved target changed what the decision read: re-decision. A token that could not run
  /// (failed, timed out) is re-planned, and re-decided once its re-plans are used up. A fixed
  /// order (it would decide the same) only re-plans. After that, or when the token's entity
  /// or target is not tracked, the run aborts naming why. 0: any of these aborts (the
  /// paper's execution). The default, 2, recovers a stall, a push or a nudged box twice
  /// before the run gives up: one more than a single perturbation needs, since a re-plan
  /// that starts next to a body may fail once more (docs/bench/dispatch.md).
  int max_replans = 2;
  /// A robot is lost for good (a dead battery, carried off the table) when it has not been
  /// tracked this long during a run, or at once when a token of it failed or timed out while
  /// it is not tracked. With max_replans > 0 the run goes on without it where the policy
  /// decides from the scene: its step is decided again, the lost robots left out of the
  /// request (DecisionRequest::lost); it aborts naming the robot and why otherwise (a fixed
  /// order names it, a decision gives it or meets it a token, a token of it in an earlier
  /// step has not ended). With max_replans 0 an untracked robot aborts the run as before.
  double robot_lost_after_s = 5;
  /// Whether a carrier's load rides in front of it (the mock robots' table) or is pushed (the
  /// real table, its simulation): a pushing carrier backs off its load when done and is
  /// judged where it then stands (exec::carrierEnd). Its followers' setting (the node reads
  /// the follower role's ~loads_ride; `ddace eval` the table's mock_robots/loads_ride).
  bool loads_ride = false;
  /// Throws ddace::Error naming the first invalid field.
  void validate() const;
};

/// The latest poses of every entity (index = task.yaml order).
struct EntityObservation {
  std::vector<Eigen::Vector2d> positions;  ///< metres, table frame
  std::vector<bool> tracked;               ///< false while the entity is missing or stale
};

struct DecisionRequest {
  uint32_t id = 0;
  int step = 0;  ///< index of the step to decide (0-based)
  /// Every decision's snapshot, oldest first; last = now. After a carrier was lost with its
  /// load, from the decision that began the task again (Coordinator::loseRobot).
  std::vector<task::Snapshot> history;
  /// Robots lost for good (CoordinatorConfig::robot_lost_after_s): the decision is made
  /// for the team without them (their positions in the snapshots mean nothing) and must
  /// give them no token.
  std::vector<int> lost;
};

/// The policy's confidence in a decision (display only; never changes what runs).
struct DecisionProbabilities {
  std::vector<double> tokens;  ///< [token] probability, [0, 1] (empty: not given)
  double end = -1;             ///< probability of END (-1: not given)
};

/// A decision as the coordinator accepted it.
struct AcceptedDecision {
  Decision decision;
  DecisionProbabilities probabilities;
};

/// A SegmentStatus as received, before any check (see Coordinator::onSegmentStatus).
struct StatusReport {
  int topic_entity = -1;  ///< entity whose status topic it arrived on (task.yaml index)
  std::string entity;     ///< the entity name the message claims
  uint32_t segment_id = 0;
  int code = 0;                   ///< raw status code; valid: Accepted..Aborted (1..5)
  double progress = 0;            ///< [0, 1]
  double distance_to_goal_m = 0;  ///< the executor's own distance (informational only)
  std::string message;
};

struct PathRequest {
  uint32_t id = 0;
  int step = 0;
  task::Token token;
  Eigen::Vector2d start{0, 0};  ///< the entity's position when the step was decided
  Eigen::Vector2d goal{0, 0};   ///< the token's end point (task/end_point.h): where the path ends
};

/// One entity's part of a step, sent to the entity's executor.
struct SegmentCommand {
  int entity = -1;
  uint32_t segment_id = 0;  ///< unique within a run; status reports refer to it
  int step = 0;
  task::Token token;
  PlannedPath path;
  Eigen::Vector2d goal{0, 0};
  double timeout_s = 0;  ///< the coordinator aborts after this long
};

/// What the caller must do after an event. Empty most of the time.
struct CoordinatorOutput {
  std::optional<DecisionRequest> decision;
  std::vector<PathRequest> paths;
  std::vector<SegmentCommand> segments;
  std::vector<int> stop;  ///< entities whose segment is cancelled: zero their wheels now
  bool stop_all = false;  ///< stop every robot (abort, e-stop, reset)
  bool state_changed = false;
  std::vector<std::string> log;  ///< what happened, for the operator

  bool empty() const {
    return !decision && paths.empty() && segments.empty() && stop.empty() && !stop_all && !state_changed;
  }
};

/// One token as it ran.
struct TokenRecord {
  task::Token token;
  double started_s = -1;        ///< when its predecessors had ended and it started (-1: waiting)
  Eigen::Vector2d start{0, 0};  ///< the entity's position when it started
  Eigen::Vector2d goal{0, 0};   ///< the end point (task/end_point.h); = start for in-place tokens
  uint32_t segment_id = 0;      ///< 0 for in-place tokens
  SegmentState state = SegmentState::Sent;
  double progress = 0;                 ///< last reported, [0, 1]
  PlannedPath path;                    ///< empty for in-place tokens
  double timeout_s = 0;                ///< the segment's time-out (0 for in-place tokens)
  double segment_sent_s = -1;          ///< when its segment went out (-1: none out)
  uint32_t path_request = 0;           ///< the path request awaited (0: none)
  double path_requested_s = -1;        ///< when it was sent
  uint32_t batch = 0;                  ///< tokens that started together share it: their segments go out together
  Eigen::Vector2d target_start{0, 0};  ///< its target's position when it was (re-)planned
  int replans = 0;                     ///< times it was re-planned (CoordinatorConfig::max_replans)
  /// Straight-line distance of the entity's *tracked* position to `goal` (metres; NaN
  /// before the first observation after the segment went out).
  double distance_to_goal_m = std::numeric_limits<double>::quiet_NaN();
  bool done_claimed = false;              ///< the executor said DONE; counted once the tracked pose agrees
  int pushed_load = -1;                   ///< the load its carrier pushes (-1: none, or it rides)
  Eigen::Vector2d pushed_load_end{0, 0};  ///< that load's end point
};

struct StepRecord {
  int step = 0;
  std::vector<TokenRecord> tokens;
  double decided_s = 0;
  double finished_s = -1;  ///< when its last token ended (-1: not yet)
  bool complete = false;
};

/// The first request and segment id of a coordinator started at `wall_clock_s` (seconds
/// since the epoch): its milliseconds, modulo 2^31, never 0. A follower takes a segment with
/// the id of the one it runs for a re-sent copy (and ignores it), the planner and the
/// sequence node answer by request id; so a coordinator restarted mid-session starts past
/// every id of the one before, which issued a few ids per step, not one per millisecond.
uint32_t firstIdAt(double wall_clock_s);

class Coordinator {
 public:
  /// `end_points`: where motions end (the model's, gp::PrimitiveLibrary::endPoints(), or
  /// learned from the demonstrations a replay runs). `first_id`: this coordinator's first
  /// request and segment id (then counting up, never 0); a coordinator restarted in a
  /// session must not repeat the ids of the one before, which the nodes may still hold (see
  /// firstIdAt). `dependencies`: the learned ones (a model's manifest, or learned from the
  /// demonstrations a replay runs; not learned: every token waits for every earlier one);
  /// `policy_reads_scene`: whether a decision depends on the positions (Dispatch::mayDecide).
  /// Throws ddace::Error when the config is invalid.
  Coordinator(task::TaskSpec spec, CoordinatorConfig config, task::EndPointModel end_points, uint32_t first_id = 1,
              graph::Dependencies dependencies = {}, bool policy_reads_scene = true);

  /// Idle -> start a run; Paused -> resume (re-plans the started tokens that had not ended).
  /// Refused (empty output and a log line) in any other state.
  CoordinatorOutput start(double now_s);
  /// Cancels the running segments (robots stop) and holds. Refused when not running.
  CoordinatorOutput pause(double now_s);
  /// Stops everything and forgets the run; also leaves EStopped.
  CoordinatorOutput reset(double now_s);
  /// Stops every robot and holds in EStopped until reset().
  CoordinatorOutput emergencyStop(double now_s, const std::string& reason);

  CoordinatorOutput onEntities(const EntityObservation& observation, double now_s);
  /// `probabilities`, when given, must have one entry per token (else the run aborts).
  CoordinatorOutput onDecision(uint32_t request_id, const Decision& decision, double now_s,
                               const DecisionProbabilities& probabilities = {});
  /// The decision asked for cannot be made (no model, bad answer): aborts with `error`.
  CoordinatorOutput onDecisionError(uint32_t request_id, const std::string& error, double now_s);
  /// A generated path. An empty `path.points` or `error` not empty aborts the run.
  CoordinatorOutput onPath(uint32_t request_id, const PlannedPath& path, const std::string& error, double now_s);
  /// Counted only when the report's entity, topic and segment id agree with the running
  /// segment and its code is valid; anything else is logged and ignored. A DONE counts
  /// only when the tracked position of the entity has arrived at the end point; until then the segment runs on (checked
  /// again on every observation) until it really arrives or times out. A disagreeing DONE is logged once per segment.
  CoordinatorOutput onSegmentStatus(const StatusReport& report, double now_s);
  /// The same for an in-process executor reporting on `entity`'s own topic (simulations,
  /// benchmarks): every check above still applies.
  CoordinatorOutput onSegmentStatus(int entity, uint32_t segment_id, SegmentState state, double progress,
                                    const std::string& message, double now_s);
  /// Time-outs only; never starts a decision.
  CoordinatorOutput onTick(double now_s);
  /// Something the run depends on is gone (a node serving a role, the pose source): stops
  /// every robot and aborts with `why`. No effect unless a run is under way (or paused).
  CoordinatorOutput abortRun(const std::string& why, double now_s);
  /// A run that was to start never could (autostart waited longer than its limit for a
  /// node, an entity or the recorder): from Idle only, Aborted with `why` and every robot
  /// told to stop, so that the record says why nothing ran. No effect in any other state.
  CoordinatorOutput abortStart(const std::string& why, double now_s);
  /// True while a run is under way: WaitingForEntities, Deciding, Planning, Executing, Paused.
  bool running() const;

  RunState state() const { return state_; }
  const std::string& reason() const { return reason_; }  ///< why Aborted/EStopped/Finished
  const task::TaskSpec& spec() const { return spec_; }
  const std::vector<StepRecord>& steps() const { return steps_; }
  /// The earliest step not yet complete, or nullptr.
  const StepRecord* currentStep() const;
  /// The latest observation (empty before the first).
  const EntityObservation& observation() const { return observation_; }
  /// Entities whose motion token started and has not ended (in any step).
  std::vector<int> activeEntities() const;
  /// The run's dispatch record: when each token started and ended, whom it waited for, the
  /// precedence violations (nullptr before the first start).
  const Dispatch* dispatch() const { return dispatch_ ? &*dispatch_ : nullptr; }
  /// Every goal condition of task.yaml against the latest positions, in order
  /// (task::goalConditionMet).
  std::vector<bool> goalConditionsMet() const;
  uint32_t decisionsRequested() const { return decisions_requested_; }
  /// The decision request awaiting its answer (0: none).
  uint32_t pendingDecision() const { return pending_decision_; }
  /// The last decision the coordinator accepted (probabilities as the policy gave them).
  const std::optional<AcceptedDecision>& lastDecision() const { return last_decision_; }
  /// Recoveries of the run so far (CoordinatorConfig::max_replans): tokens re-planned,
  /// steps re-decided.
  int replans() const { return replans_; }
  int redecisions() const { return redecisions_; }
  /// The steps withdrawn by a re-decision, as they stood then (oldest first).
  const std::vector<StepRecord>& withdrawnSteps() const { return withdrawn_; }
  /// Robots lost for good during the run, with why ("R1: not tracked for 5 s").
  const std::vector<std::string>& lostRobots() const { return lost_reports_; }
  /// The entities of the robots lost for good in this run, in task order.
  std::vector<int> lostEntities() const;

 private:
  bool allTracked() const;
  void setState(RunState s, CoordinatorOutput& out);
  /// After every event of a run: starts what may start, plans it, completes steps, asks for
  /// the next decision when it may, finishes after END, and sets the state.
  void advance(double now_s, CoordinatorOutput& out);
  void startReady(double now_s, CoordinatorOutput& out);
  void requestPaths(const std::vector<TokenRef>& tokens, double now_s, CoordinatorOutput& out);
  void sendBatch(uint32_t batch, double now_s, CoordinatorOutput& out);
  /// The path of started token `t` from its planned one: a carrier's pushes its load
  /// (exec/push_path.h) and ends behind the load's end point (its goal moves to where it
  /// then stands, exec::carrierEnd), any other is `planned`.
  PlannedPath carrierPath(TokenRef t, const PlannedPath& planned);
  /// A pushing carrier that said DONE is judged behind where its load is tracked now
  /// (exec::carrierEnd, as the simulator judges it): its goal moves there.
  void judgeBehindItsLoad(TokenRecord& t);
  void requestDecisionIfDue(double now_s, CoordinatorOutput& out);
  /// A decision asked ahead from the predicted scene (a policy that reads the scene, under
  /// async) holds once every step before it has ended and every entity stands within
  /// arrival_radius_m + arrival_tolerance_m of where that scene put it (its snapshot then
  /// becomes the scene as it is); else it is withdrawn (withdrawAhead) and asked for again
  /// from the scene as it is.
  void settleAhead(CoordinatorOutput& out);
  /// Withdraws the decision asked ahead and not yet held -- its request, its step (the
  /// tokens under way stopped; those that ended stay done on the table) or its END --
  /// naming `why`. No effect when there is none.
  void withdrawAhead(const std::string& why, CoordinatorOutput& out);
  /// The first motion of a decided step whose motion class (task::motionClass: the mover's
  /// kind, whether it carries a load, the target's kind) no demonstration has, as "R1:carry:B2
  /// (robot+load->object)"; "" when every one was demonstrated or nothing was learned (a model
  /// whose motions end at centres). Such a motion has no learned path or end: a team bound
  /// without a lost robot decided what its training never showed.
  std::string undemonstratedMotion(const std::vector<task::Token>& tokens) const;
  /// Per token of a step decided from `scene`: the robot tokens of the step bound for the
  /// same target whose end point lies nearer it (by more than arrival_tolerance_m), which
  /// start before it (Dispatch::addStep's start_after): places at one target are taken from
  /// the inside out, as from the common start the demonstrations showed. Released first, the
  /// outer one (Task 4's R4, ending 4.4 cm short of G1) stands on the inner one's way in.
  std::vector<std::vector<int>> insideOut(const std::vector<task::Token>& tokens,
                                          const std::vector<Eigen::Vector2d>& scene) const;
  /// The first entity (not lost) `settled` farther than the arrival radius and tolerance
  /// from where `predicted` put it, and how far ("" when none is).
  std::string unlikePrediction(const std::vector<Eigen::Vector2d>& predicted,
                               const std::vector<Eigen::Vector2d>& settled) const;
  /// The scene `at` (as it is, or as decisionScene reads it) as the decided steps will leave
  /// it: every entity of a token that has not ended at its end point (a started one at its
  /// goal), step after step. What a decision asked ahead reads (a fixed order always), as its
  /// demonstrations showed it a step's end.
  std::vector<Eigen::Vector2d> sceneOnceSettled(std::vector<Eigen::Vector2d> at) const;
  /// What a decision of a policy that reads the scene reads: the scene as it is, but an
  /// entity a re-decided step had moved that now stands at one place with another
  /// (task::together) where that step began (began_at_): at one place the policy reads a
  /// robot as having gone there -- it saw a robot beside a box only once it fetched it.
  std::vector<Eigen::Vector2d> decisionScene() const;
  /// The step (or END) just decided in place of a re-decided one is recorded with began_at_'s
  /// entities where that step began; decided ahead, began_at_ is kept until the scene settles
  /// (settleAhead records the settled scene with them there too), else cleared.
  void recordBeganAt();
  void refreshState(CoordinatorOutput& out);
  void abort(const std::string& why, CoordinatorOutput& out);
  void stopActive(CoordinatorOutput& out);
  bool arrived(const TokenRecord& t) const;
  void updateDistances();
  /// Re-plans a started token from the scene as it is, or aborts naming `why` when it may
  /// not (CoordinatorConfig::max_replans).
  void replan(TokenRef t, const std::string& why, double now_s, CoordinatorOutput& out);
  /// Recovers `t` (see max_replans): re-decides its step when `target_moved` or its re-plans
  /// are used up, else re-plans it; re-decides only the latest step of a policy that reads
  /// the scene.
  void recover(TokenRef t, const std::string& why, bool target_moved, double now_s, CoordinatorOutput& out);
  /// `begin_again`: the policy is asked for its first step from the scene as it is (its
  /// history starts again with this decision), not for the withdrawn one.
  void redecide(TokenRef t, const std::string& why, double now_s, CoordinatorOutput& out, bool begin_again = false);
  /// The load that the robot's unfinished motion `t` carries: an object's unfinished motion
  /// of its step with its action and target ("" for none).
  std::string loadOf(TokenRef t) const;
  /// The robot of its step that pushes object motion `t` (loads not riding), or "" (a load
  /// riding, or moved by no robot of its step). Nothing else moves a pushed load: its own
  /// segment sent again would have the table move it by hand.
  std::string pusherOf(TokenRef t) const;
  /// Aborts naming `why` and returns false when `t` may not be recovered once more
  /// (`done` of max_replans done, or its entity or target not tracked).
  bool mayRecover(TokenRef t, int done, const std::string& why, CoordinatorOutput& out);
  /// Robots untracked past robot_lost_after_s are lost (with recovery on).
  void checkLost(double now_s, CoordinatorOutput& out);
  /// Robot `e` is lost for good: the run goes on without it, or aborts naming it and `why`
  /// (CoordinatorConfig::robot_lost_after_s).
  void loseRobot(int e, const std::string& why, double now_s, CoordinatorOutput& out);
  std::string lostWhy(int e) const;  ///< why robot `e` was lost ("" if it was not)
  /// The end point of the started token `t` from the positions `at` (the step's other
  /// started tokens at their start).
  Eigen::Vector2d endPointOf(TokenRef t, std::vector<Eigen::Vector2d> at) const;
  /// Marks `t` done and ends it in the dispatch record.
  void endToken(TokenRef t, double now_s, CoordinatorOutput& out, const std::string& why);
  TokenRecord& record(TokenRef t) { return steps_[static_cast<size_t>(t.step)].tokens[static_cast<size_t>(t.index)]; }
  /// The started token whose segment or path request has `id` (segment: `by_segment`).
  std::optional<TokenRef> findRunning(uint32_t id, bool by_segment) const;
  void clearRun();
  uint32_t nextId();  ///< next_id_, then counts up past 0

  task::TaskSpec spec_;
  CoordinatorConfig config_;
  task::EndPointModel end_points_;
  graph::Dependencies dependencies_;
  bool policy_reads_scene_ = true;
  std::optional<Dispatch> dispatch_;
  RunState state_ = RunState::Idle;
  std::string reason_;
  EntityObservation observation_;
  /// Per entity: where the tracker last saw it (NaN: never). A robot the tracker lost still
  /// stands there, and a push is planned round it.
  std::vector<Eigen::Vector2d> last_seen_;
  std::vector<task::Snapshot> history_;
  size_t history_from_ = 0;  ///< the policy's history begins here (the task begun again)
  /// The decision asked ahead from a predicted scene and not yet held (settleAhead): its
  /// snapshot's index in history_ (= its step's, or steps_.size() for END); -1: none.
  int ahead_ = -1;
  std::vector<StepRecord> steps_;
  uint32_t next_id_ = 1;
  uint32_t next_batch_ = 1;
  uint32_t pending_decision_ = 0;
  double decision_since_s_ = 0;
  bool end_decided_ = false;           ///< the policy said END; finished once every token ended
  bool waiting_for_entities_ = false;  ///< a decision is due but an entity is not tracked
  bool blocked_on_tracking_ = false;   ///< a ready token waits for its entities to be tracked
  uint32_t decisions_requested_ = 0;
  std::optional<AcceptedDecision> last_decision_;
  int replans_ = 0, redecisions_ = 0;
  std::vector<int> step_redecisions_;  ///< per step index: times it was re-decided
  std::vector<StepRecord> withdrawn_;
  /// A re-decided step's entities that its withdrawn tokens had moved, where they stood in
  /// the scene it was decided from (decisionScene); the step decided again is recorded with
  /// them there, so the decisions after it read its motion from where it began. Kept until
  /// that step holds: decided from the scene as it is, or decided ahead and settled.
  std::vector<std::pair<int, Eigen::Vector2d>> began_at_;
  std::vector<bool> lost_;               ///< per entity: a robot lost for good
  std::vector<double> untracked_since_;  ///< per entity: since when not tracked (-1: tracked)
  std::vector<std::string> lost_reports_;
};

}  // namespace ddace::exec
