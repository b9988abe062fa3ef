// The tgn module's internals on plain arrays and task data (the step decoder, the name
// groups, the attention edges), which the networks use and the tests and benchmarks reach
// directly: not the API of the commands and nodes (sequence_model.h). No torch here.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "ddace/graph/refinement.h"
#include "ddace/task/task_dir.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::tgn {

/// For the benchmarks' Python reference: writes the keyframe training tensors of `train`
/// (normalised inputs, targets, masks, attention mask) as whitespace-separated text, for the
/// network SequenceModel::train(train, options) trains ("Fixed order" rule applied).
void writeTrainingTensors(const task::TaskDir& train, const TrainOptions& options, const std::string& path);

namespace detail {
/// One GAT layer on plain arrays, through the same module the network uses (tests).
struct GatWeights {
  int in = 0, heads = 0, channels = 0;
  std::vector<float> weight;   ///< [heads*channels][in], row-major (torch Linear layout)
  std::vector<float> att_src;  ///< [heads][channels]
  std::vector<float> att_dst;  ///< [heads][channels]
  std::vector<float> bias;     ///< [heads*channels]
};
/// x: [nodes][in] row-major. Messages flow along `edges` (source -> target), self-loops
/// are added. Returns [nodes][heads*channels] row-major.
std::vector<float> gatForward(const GatWeights& w, const std::vector<float>& x, int nodes,
                              const std::vector<graph::Edge>& edges);
/// The groups of entities (task indices, each ascending; groups by their first) whose
/// identity embeddings training shuffles among themselves (TrainingPlan::name_groups).
/// An entity's role in a demonstration is what its tokens are, per step: as actor (the
/// action and the target's kind) and as target (the action and the actor's kind). An
/// entity keeps its name when it plays one role in every demonstration and no other
/// entity of its kind plays that role too (queue's slots Q1, Q2, Q3: the name says
/// which step fills it), and when the rule refers to it by name: a nearness or farness
/// rank of it to a token's participant has one value in every demonstration and, for its
/// mates, so rarely that the names are not interchangeable ("the others meet at the robot
/// nearest to G1"; binomial tail at the mates' rate < 1e-3). The other entities of each
/// kind form a group (only groups of two or more are returned). "Every demonstration"
/// allows labelling slips: all but at most one in ten of them (rounded down), as
/// task::commonSteps.
std::vector<std::vector<int>> interchangeableNames(const task::TaskDir& train);
/// E' lifted to entity kinds (the scene network's attention edges): every ordered pair of
/// distinct entities of `to` whose kinds are those of one of `edges` (entities of `from`).
std::vector<graph::Edge> liftedToKinds(const std::vector<graph::Edge>& edges, const task::TaskSpec& from,
                                       const task::TaskSpec& to);
/// The training's stopping rule (see "stopping" above) on the epochs so far.
bool atPlateau(const std::vector<EpochRecord>& history, int patience, double delta);

/// Entities at one place: per entity the lowest index of those at one place with it,
/// transitively (a chain, each within its pair's `together` distance [N * N] of the next).
std::vector<int> placesOf(const std::vector<Eigen::Vector2d>& pos, const std::vector<double>& together);
/// Per pair of kinds (kindKey) of `spec`: how many entities of the first are themselves at
/// one place with an entity of the second (another one, where the kinds are the same) at
/// `pos` (task order), not through a neighbour as placesOf joins them. Pairs with no such
/// entity are left out.
std::map<std::pair<std::string, std::string>, int> endCountsOf(const task::TaskSpec& spec,
                                                               const std::vector<Eigen::Vector2d>& pos);
/// "End scene": what the last scene of every demonstration of `train` had in common
/// (EndScene). None from fewer than two demonstrations.
EndScene endSceneOf(const task::TaskDir& train);
/// `end` of a model of `trained` on the entities of `other`: a count follows the counts it was
/// all of in training (every entity of its kind, or of the kind it is with), the least of
/// those in `other`, and grows no further than every kind it was all of grew; any other
/// stays, at most the entities of its kind in `other`. `waits`,
/// per count of the result: it grew past training's (END waits for it).
EndScene endSceneFor(const EndScene& end, const task::TaskSpec& trained, const task::TaskSpec& other,
                     std::vector<bool>& waits);
/// p(END) under `end` at `pos` (task order): 0 while a count that waits (`waits`, per count;
/// empty: none) does not hold; 1 once every count holds, where they tell the end; else `p`.
double endProbability(double p, const EndScene& end, const std::vector<bool>& waits, const task::TaskSpec& spec,
                      const std::vector<Eigen::Vector2d>& pos);
/// What the scene at `pos` (task order) lacks of `end`, entities counted as at one place
/// through neighbours too (placesOf; a carrier behind the load it pushed onto a goal is at the
/// goal): per count that does not hold, "N <kind> with <with> (M here)" ("with another" where
/// the kinds are the same), joined by "; ". "" when every count holds (or `end` has none).
std::string endSceneShort(const EndScene& end, const task::TaskSpec& spec, const std::vector<Eigen::Vector2d>& pos);
/// Each entity's last move, the relational basis's (the latest step of `history`'s first
/// `count` snapshots in which it moved more than the arrival radius): the node it went to (the
/// entity ahead it stopped where a motion toward it ends), or -1 (never moved, or nothing lay
/// ahead). Nodes in `entity_of`'s order (entity_of[i]: node i's entity of `spec`).
std::vector<int> lastMoves(const task::TaskSpec& spec, const std::vector<int>& entity_of,
                           const std::vector<Eigen::Vector2d>* history, size_t count);
/// "Next targets": every transition of `train`'s tokens (NextTarget): an acting entity's
/// kind, the kind its last move went to as the step began (lastMoves), its target's kind.
std::vector<NextTarget> nextTargetsOf(const task::TaskDir& train);
/// Under `rule` (TrainingPlan::next_targets), per node and target slot [n][n + 1] (slot 0 in
/// place, k node k-1; nodes as lastMoves'): may it take that target next. An entity whose
/// kind took no token after a last move to its last move's kind is not restricted (nothing
/// was shown), nor is any where `rule` is empty.
std::vector<bool> nextTargetsAllowed(const std::vector<NextTarget>& rule, const task::TaskSpec& spec,
                                     const std::vector<int>& entity_of, const std::vector<Eigen::Vector2d>* history,
                                     size_t count);
/// The counts a count of training follows to another task: each (training count, other
/// count) it equals; the least of the other counts, or -1 when it equals none.
int followedCount(int count, const std::vector<std::pair<int, int>>& trained_and_other);

/// One entity's decoded output: action class (0 = idle, c = vocabulary[c-1]) and target
/// slot (0 = no target, k = entity k-1), both in the network's canonical order.
struct DecodedToken {
  int action = 0;
  int target = 0;
  bool operator==(const DecodedToken& o) const { return action == o.action && target == o.target; }
};
/// The step decoder predictNext uses (StepRules in sequence_model.h), on plain arrays:
/// log_action [n][actions], log_target [n][targets], row-major log-probabilities.
std::vector<DecodedToken> decodeStep(const std::vector<double>& log_action, int actions,
                                     const std::vector<double>& log_target, int targets, const StepRules& rules);
/// log P(step) under the heads: the sum over the entities of log p(action), plus
/// log p(target) for those that act (log-probabilities floored at -1000, as decodeStep).
double stepLogProbability(const std::vector<DecodedToken>& step, const std::vector<double>& log_action, int actions,
                          const std::vector<double>& log_target, int targets);

/// END is decided when p(END) is above this.
inline constexpr double kEndThreshold = 0.5;

/// What predictNext hands on: END, or a step in which at least one entity acts.
struct StepDecision {
  bool end = false;
  std::vector<DecodedToken> tokens;  ///< one per entity (all idle when end)
};
/// "Ensemble" (docs/tgn.md): the index of the decision to keep of those its networks
/// decoded, one each: the one most of them decoded (END, or the same tokens), on a tie the
/// first network's of the tied ones. Throws ddace::Error for none.
size_t majorityDecision(const std::vector<StepDecision>& decisions);
/// Two networks decided the same step: both END, or the same tokens (the vote's equality).
bool sameDecision(const StepDecision& a, const StepDecision& b);
/// The decision of one step, never an empty step: END when p(END) > kEndThreshold; else
/// decodeStep's step; when every entity of that is idle, the most probable step S* in which
/// one acts (the joint decoder's best under `rules` with some entity forced to act; the
/// lowest such entity on ties), or END instead when p(END) >= (1 - p(END)) * P(S*), the
/// more probable of the two. Throws ddace::Error for a p(END) that is not a probability.
StepDecision decideStep(double end_probability, const std::vector<double>& log_action, int actions,
                        const std::vector<double>& log_target, int targets, const StepRules& rules);

/// An object and the entities at its place (not objects) as a step begins: who can carry it.
struct Load {
  int object = 0;
  std::vector<int> carriers;
};
/// Carried loads: each object (in `entity_of`'s order: entity_of[i] is node i's entity of
/// `spec`) with the entities, not objects, that can carry it as a step begins: those at its
/// place (task::together) whose nearest object at their place it is. A robot stands at one
/// load's place at most: a carrier beside another pair's box (two pairs fetched side by
/// side) is that box's neighbour, not its carrier. Ties go to the first object.
std::vector<Load> loadsAt(const task::TaskSpec& spec, const std::vector<int>& entity_of,
                          const std::vector<Eigen::Vector2d>& pos);
/// Carried loads (StepRules::load_actions): a load and its carrier are one decision. For
/// each load whose tokens in `step` break the rule (the load takes a load action that no
/// entity at its place takes with the same target, or one of them takes a load action
/// without it), the most probable of: the load idle and none of them with a load action
/// (each falls back to its best token without one), or the load and one of them with the
/// same load action and target. `load_action` [actions]: true for the load actions'
/// classes. The heads as decodeStep's. Steps that keep the rule are left as they are.
void coupleLoads(std::vector<DecodedToken>& step, const std::vector<double>& log_action, int actions,
                 const std::vector<double>& log_target, int targets, const std::vector<Load>& loads,
                 const std::vector<bool>& load_action);

}  // namespace detail

}  // namespace ddace::tgn
