// Tokens and steps inferred from a demonstration's motion (docs/labels.md), with action
// words from a hand-labelled example, and everything the motion does not decide surely
// reported as a note on the row where it happens.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "ddace/label/inference.h"
#include "ddace/task/demonstration.h"

namespace ddace::label {

/// One inferred token and the rows its label holds (the step's first onset to its own end).
struct InferredToken {
  task::Token token;
  int first_row = 0, last_row = 0;
  int onset_row = 0;      ///< where the entity itself started to move (the step's keyframe for in-place)
  int carrier = -1;       ///< for a load: the entity that carried it
  int load = 0;           ///< 1: it carried a load, 2: it was one (kindKey)
  bool in_place = false;  ///< an in-place action taken from the example
  std::vector<int> tied;  ///< the entities its end point could not tell apart (target among them)
  std::string kind;       ///< kindKey(): what decides its word
  bool unsure = false;    ///< listed to check: a note names it and the alternative considered
  std::string doubt;      ///< the first note that listed it
};

struct InferredStep {
  int keyframe_row = 0;
  std::vector<InferredToken> tokens;  ///< by entity
};

/// Something the motion did not decide surely, at a row (file line = row + 2).
struct Note {
  int row = 0;
  std::string message;
  int entity = -1;  ///< the entity whose token it doubts (-1: no one token)
};

struct Inference {
  std::vector<InferredStep> steps;
  std::vector<Note> notes;  ///< in row order
};

/// The kind of a motion, which decides its action word: mover kind/type, target
/// kind/type, and whether it carried a load ("+load") or was one ("+carried").
std::string kindKey(const task::TaskSpec& spec, int mover, int target, int load);
/// The same without the types: the fallback when the example has no motion of the exact kind.
std::string coarseKindKey(const task::TaskSpec& spec, int mover, int target, int load);

/// What a demonstration labelled by hand teaches (`ddace label --example`): the word of
/// every kind of motion, its steps (so a demonstration whose motion has the example's
/// steps gets its in-place actions and its choice between entities stacked on one spot),
/// and which kind of entity it chose when an end point was a tie.
struct Example {
  std::string source;
  std::map<std::string, std::string> words;  ///< kindKey / coarseKindKey -> action
  std::vector<task::Step> steps;             ///< as labelled
  /// tied kinds ("goal,object,robot", and as classes "body,goal") -> the kind chosen
  std::map<std::string, task::EntityKind> tie_kind;
  /// Some step sends a robot to an entity that moves in the same step (a robot following
  /// another): without one, a motion ending at such a mover stopped at where it went.
  bool sends_to_movers = false;
  /// Reads the example's words off its own motion and labels. Throws ddace::Error naming
  /// `d.source` when it has no labelled motion.
  static Example fromDemonstration(const task::Demonstration& d, const task::TaskSpec& spec);
};

/// Infers the labels of one demonstration, row by row. A step is decided as soon as no
/// later row can change it (every entity of it has rested for pause_s beyond the rows
/// the segmenter keeps, and no running motion began before its end): take() hands over
/// what is decided, so a recording of any length is labelled in memory bounded by a few
/// seconds of rows and motions (with an example: plus the example's steps, held until
/// the demonstration is known to have more steps than it). The steps are the same
/// whether or not take() is called.
class Labeller {
 public:
  explicit Labeller(const task::TaskSpec& spec, const Example* example = nullptr);
  void row(double t, const std::vector<Eigen::Vector2d>& positions);
  /// The steps decided since the last take() (in row order) and their notes (in row
  /// order within one take()).
  Inference take();
  /// The steps and notes not taken yet (everything when take() was never called, notes
  /// in row order); call once after the last row.
  Inference finish();
  int rows() const { return segmenter_.rows(); }

 private:
  struct Group {
    std::vector<Motion> motions;
    std::vector<Note> notes;  ///< of its grouping, handed over with its step
  };
  /// Goal motions become notes; the others wait in pending_.
  void arrive(std::vector<Motion> found);
  /// Merges pauses and groups the pending motions; hands over the groups no later row
  /// can change (all of them `at_end`).
  void decide(bool at_end);
  /// The pending motions, each joined with the next of its entity across a pause.
  std::vector<Motion> joinPauses() const;
  /// Drops the motions that end where they began (bumped and put back), unless they moved
  /// an object farther.
  void dropNudges(std::vector<Motion>& merged) const;
  /// Drops the pieces of steps handed over already; a motion begins after the last one.
  void dropHandedOver(std::vector<Motion>& merged) const;
  /// Motions that overlap in time, as steps (one motion per entity and step); `group_off`
  /// gets each group's last offset row.
  std::vector<Group> groupSteps(std::vector<Motion> merged, std::vector<int>& group_off) const;
  /// How many of the groups, in order, no later row can change.
  size_t finalGroups(const std::vector<Group>& groups, const std::vector<int>& group_off,
                     const std::vector<int>& last_on, const MotionSegmenter::Horizon& horizon) const;
  /// A final group: joined with the next when together they are the example's step
  /// (partial_), then place()d.
  void handOver(Group g);
  /// A group of its own: straight to emit(), or held while the example's alignment is open.
  void place(Group g);
  /// The movers of the example's motion step k (none past its last).
  std::set<int> exampleMovers(size_t k) const;
  /// How many of each kind `entities` has.
  std::map<task::EntityKind, int> kindsOf(const std::set<int>& entities) const;
  /// "2 robots and 1 object".
  static std::string kindsText(const std::map<task::EntityKind, int>& kinds);
  /// The example's alignment is settled: emits the held groups.
  void settle(bool aligned);
  /// The step(s) of one group (and the example's in-place steps before it) into out_.
  void emit(Group& g, bool aligned);
  /// Notes (once) that step k's movers are not the kinds of the example's step k.
  void noteStepsDiffer(size_t k, const std::vector<Motion>& g, int row);
  /// Every motion of `g` ended at (together with) a body that moved in `first`, the group
  /// before it: it joined them (a robot held back until there was room at the crowd).
  bool joinedItsBodies(const Group& g, const Group& first) const;
  /// A motion token to the entity its entity's last motion ended at, which has not moved
  /// since, is noted: no new place (a bump put back, or a piece of that motion?).
  void noteArrivedAgain(const std::vector<Motion>& g, const std::vector<InferredToken>& tokens);
  /// For each motion of a group, the index of the robot motion it is the load of, or -1.
  std::vector<int> carriersOf(const std::vector<Motion>& g) const;
  /// Tokens of a group's motions: targets (carriers and lone movers first, then their
  /// loads) and action words.
  std::vector<InferredToken> motionTokens(const std::vector<Motion>& g, const std::vector<int>& carrier, int first_row,
                                          size_t k, bool aligned);
  /// A motion that ended at a mover of its step which itself went to another entity T (a
  /// crowd round T): T when the example never sends a robot to a mover of its step, else
  /// listed with T as the alternative.
  void readChain(std::vector<InferredToken>& tokens, const std::vector<Motion>& g, const std::vector<int>& carrier);
  /// The target of a motion that is no load (endPoint(); a tie resolved by the example).
  /// One that stopped away from every entity is read again among the bodies as they stood
  /// when its step ended (`step_end`): others of the step may have come to its target
  /// after it stopped, in front of it.
  void readTarget(InferredToken& tok, const Motion& m, int load, size_t k, bool aligned,
                  const std::vector<Motion>& step, const std::vector<Eigen::Vector2d>& step_end);
  /// `m` stopped within the arrival radius of touching `body`, the body ahead of it (within a
  /// right angle of its heading).
  bool stoppedShortFacing(const Motion& m, int body) const;
  /// `m` stopped short facing (stoppedShortFacing) a body that moved in its `step` and stands
  /// nearer `target` than it: in a row behind it, not halfway (its target is not listed).
  bool behindARow(const Motion& m, int target, const std::vector<Motion>& step) const;
  /// Between the tied end points of `ep`: the example's step k (aligned), the example's
  /// choice between such kinds, or its only motion of the kind; else noted.
  void resolveTie(InferredToken& tok, const Motion& m, const EndPoint& ep, size_t k, bool aligned);
  /// The action word of a token with its target; true when it noted an object moving alone.
  bool nameAction(InferredToken& tok, const Motion& m, bool is_load);
  /// Notes a body a motion nearly stopped at on its way, keeping its heading.
  void noteStopsOnTheWay(const std::vector<Motion>& g, const std::vector<int>& carrier,
                         const std::vector<InferredToken>& tokens);
  /// Marks the tokens that a note since `notes_from` doubts (a load with its carrier).
  void markUnsure(std::vector<InferredToken>& tokens, size_t notes_from) const;
  void note(int row, const std::string& message, int entity = -1) { out_.notes.push_back({row, message, entity}); }
  /// Cuts motions where what moves with them changes: a robot that reaches an object and
  /// pushes it on without stopping (at the object's onset), an object handed on at contact
  /// from one robot to another (where the receiver starts); and where a robot stopped at
  /// a body without a pause and left in another heading.
  void cutAtContacts(std::vector<Motion>& motions) const;
  /// `m` came to body `b` on its way (from farther than the arrival radius), touched it,
  /// nearly stopped there (under a quarter of its mean speed) and left it again (farther
  /// than the arrival radius): a stop there, or a slow pass. `turn`: radians between the
  /// heading it came in and the one it left in.
  bool stoppedAtOnItsWay(const Motion& m, int b, double& turn) const;
  bool together(const std::vector<Eigen::Vector2d>& at, int a, int b) const;
  /// `m` is with an object at its onset, at `at` and at its offset, and the object moved
  /// with it: a robot going round its load to the side it pushes from (a slow turn beside
  /// a body there is no stop).
  bool goesRoundItsLoad(const Motion& m, const std::vector<Eigen::Vector2d>& at) const;
  /// `m` begins as the motions of a step have stopped (the last at step_off_t), within
  /// the precision onsets and offsets are dated to: a step of its own, even with no pause
  /// (a stop at contact followed by a change of what moves).
  bool startsAStep(double step_off_t, const Motion& m) const;
  bool staysWith(const Motion& m, int j) const;
  /// Object motion `o` went with robot motion `r` (overlapping in time, `r`'s robot at one
  /// place with the object all the way): however little the robot itself moved (turning
  /// in place sweeps what it touches round it), it moved the object.
  bool sweptBy(const Motion& o, const Motion& r) const;
  std::vector<bool> candidatesOf(const Motion& m) const;
  bool pausedOnItsWay(const Motion& a, const Motion& b) const;
  /// `a` went a short way (under twice a nudge) and `b`, its entity's next motion, heads
  /// back to where `a` began: a hand's bump and its put-back.
  bool headsBack(const Motion& a, const Motion& b) const;
  /// headsBack(), `b` within pause_s of `a` and ending within a nudge of where `a` began:
  /// together they went nowhere (a nudge), whatever came before them.
  bool bumpedAndPutBack(const Motion& a, const Motion& b) const;
  /// Object motion `a` went with no robot's motion, at one place with a resting robot all the
  /// way, and `b`, its next, went with that robot's motion: one carry (a box swung round a
  /// robot turning in place, then pushed on by it).
  bool swungBeforeItsCarry(const Motion& a, const Motion& b) const;
  /// Robot motion `a` (its `load` in front, -1 for none) stopped short of `body` and `b`, its
  /// next motion, went on to touch it: the last of the approach (a person closing in), not a
  /// motion of its own.
  bool closedIn(const Motion& a, const Motion& b, int body, int load) const;
  /// An object was with `a`'s robot (at a's onset, or set moving at its touch during `a`)
  /// and when it stopped, and went on farther than a nudge before `b` began: it let go.
  bool letGo(const Motion& a, const Motion& b) const;
  const task::ActionRule* rule(int mover, int target, int load) const;
  std::string word(int mover, int target, int load, int row);
  void placeInPlace(const std::vector<const task::Step*>& steps, int from, int to);

  const task::TaskSpec& spec_;
  const Example* example_;
  SegmentationOptions options_;
  MotionSegmenter segmenter_;
  std::vector<Motion> pending_;  ///< motions of steps not decided yet
  double next_check_t_;          ///< decide() again once the horizon passes this time
  // The example's motion steps and the in-place-only steps before each of them.
  std::vector<const task::Step*> ex_motion_;
  std::vector<std::vector<const task::Step*>> ex_inplace_before_;
  bool ex_has_inplace_ = false;
  enum class Alignment { Open, Aligned, NotAligned } alignment_;
  std::vector<Group> held_;  ///< final groups while alignment_ is Open
  /// A final group with some of the movers of the example's next step, waiting for a
  /// group with the others (robots of one step started apart).
  std::optional<Group> partial_;
  size_t groups_seen_ = 0;  ///< groups place()d
  size_t emitted_groups_ = 0;
  /// A step had other kinds of movers than the example's: every token from there is listed.
  bool steps_differ_ = false;
  std::string steps_differ_note_;  ///< its note, which lists every later token
  int prev_off_ = -1;              ///< the last emitted group's offset row
  /// [entity] the target of its last motion token (-1: none yet), the target's position
  /// when that motion ended, and the row it ended on.
  struct LastArrival {
    int target = -1;
    Eigen::Vector2d target_at = Eigen::Vector2d::Zero();
    int row = -1;
  };
  std::vector<LastArrival> last_arrival_;
  int handed_off_ = -1;  ///< the last offset row of the groups handed over
  Inference out_;        ///< decided, not taken
};

/// inferLabels over a demonstration in memory.
Inference inferLabels(const task::Demonstration& d, const task::TaskSpec& spec, const Example* example = nullptr);

/// The label of every entity row by row, from an inference or a stream of token spans
/// (for writing a recording as a stream): call at(row) with increasing rows.
class LabelCursor {
 public:
  /// The rows a token's label holds (first..last), in order of `first`.
  struct Span {
    int first = 0, last = 0, entity = 0;
    task::Label label;
  };
  LabelCursor(const Inference& inference, size_t entities);
  /// Spans from `next` (false at the end), in order of their first row: a span out of
  /// order throws ddace::Error.
  LabelCursor(std::function<bool(Span&)> next, size_t entities);
  const std::vector<task::Label>& at(int row);
  /// True when every span was reached by at().
  bool exhausted();

 private:
  bool peek();
  std::function<bool(Span&)> next_;
  std::vector<Span> spans_;  ///< from an inference, by first row
  size_t index_ = 0;
  std::optional<Span> ahead_;
  int last_first_ = -1;
  std::vector<Span> open_;
  std::vector<task::Label> labels_;
};

/// Replaces `d`'s labels by the inference's (label columns for every entity with a
/// token) and analyzes it again.
void applyLabels(task::Demonstration& d, const Inference& inference);

/// True when `d` has no labels: no label columns, or every action idle or empty.
bool unlabelled(const task::Demonstration& d);

}  // namespace ddace::label
