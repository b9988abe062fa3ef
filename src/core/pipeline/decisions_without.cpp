// A learned model deciding for the team without robots lost for good
// (include/ddace/pipeline/decisions_without.h).
#include "ddace/pipeline/decisions_without.h"

#include <algorithm>
#include <string>

#include "ddace/common/error.h"

namespace ddace::pipeline {

DecisionsWithout::DecisionsWithout(const tgn::SequenceModel& model) : model_(model) {}

namespace {

/// `p` for the team without `lost`: never an END the scene says leaves the task undone (a
/// team smaller than the demonstrations' cannot count on the END head's count of the steps).
tgn::Prediction finishing(tgn::Prediction p, const std::string& lost) {
  const std::string why = unfinishedEnd(p, lost);
  if (!why.empty()) throw Error(why);
  return p;
}

}  // namespace

tgn::Prediction DecisionsWithout::predict(const std::vector<task::Snapshot>& history, const std::vector<int>& lost) {
  if (lost.empty()) return model_.predictNext(history);
  const task::TaskSpec& spec = model_.spec();
  const int n = static_cast<int>(spec.entities.size());
  std::string names;
  for (int e : lost) {
    if (e < 0 || e >= n) throw Error("a lost entity index " + std::to_string(e) + " is not in the task");
    names += (names.empty() ? "" : ", ") + spec.entities[static_cast<size_t>(e)].name;
  }
  if (!bound_ || bound_lost_ != lost) {
    task::TaskSpec without = spec;
    without.entities.clear();
    kept_.clear();
    for (int i = 0; i < n; ++i)
      if (std::find(lost.begin(), lost.end(), i) == lost.end()) {
        kept_.push_back(i);
        without.entities.push_back(spec.entities[static_cast<size_t>(i)]);
      }
    without.goal_conditions.clear();  // those naming a lost robot cannot hold
    for (const task::GoalCondition& g : spec.goal_conditions)
      if (without.entityIndex(g.entity) >= 0 && without.entityIndex(g.at) >= 0) without.goal_conditions.push_back(g);
    try {
      bound_ = std::make_unique<tgn::SequenceModel>(model_.boundTo(without));
    } catch (const Error& e) {
      bound_.reset();
      throw Error("the model cannot decide without " + names + ": " + e.what());
    }
    bound_lost_ = lost;
  }
  std::vector<task::Snapshot> reduced = history;
  for (task::Snapshot& snap : reduced) {
    if (snap.positions.size() != spec.entities.size())
      throw Error("a snapshot has " + std::to_string(snap.positions.size()) + " positions for " + std::to_string(n) +
                  " entities");
    std::vector<Eigen::Vector2d> at;
    for (int i : kept_) at.push_back(snap.positions[static_cast<size_t>(i)]);
    snap.positions = std::move(at);
  }
  tgn::Prediction p = bound_->predictNext(reduced);
  for (task::Token& t : p.tokens) {
    t.entity = kept_.at(static_cast<size_t>(t.entity));
    if (t.target >= 0) t.target = kept_.at(static_cast<size_t>(t.target));
  }
  return finishing(std::move(p), names);
}

std::string unfinishedEnd(const tgn::Prediction& p, const std::string& lost) {
  if (!p.end || p.end_short.empty()) return "";
  return (lost.empty() ? std::string("END") : lost + " is lost and END for the team left") +
         " would leave the task undone: every demonstration ended with " + p.end_short +
         (lost.empty() ? "" : "; no decision without it");
}

}  // namespace ddace::pipeline
