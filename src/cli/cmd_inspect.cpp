// ddace inspect: what a model directory holds (checked on the way: every file is read).
#include <iomanip>
#include <iostream>
#include <sstream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/tgn/sequence_model.h"

namespace ddace::cli {
namespace {

/// What every training demonstration's last scene had in common (docs/tgn.md, "End scene").
std::string endSceneText(const tgn::EndScene& end) {
  std::string counts;
  for (const tgn::EndCount& c : end.counts)
    counts += (counts.empty() ? "" : ", ") + std::to_string(c.count) + " " + c.kind + " at one place with " +
              (c.with == c.kind ? "another " : "") + c.with;
  if (counts.empty()) return "none (the END head decides)";
  return counts + (end.telling ? " (held in no earlier scene: END once it holds)"
                               : " (held in an earlier scene too: the END head decides; on a larger team, not "
                                 "before this holds)");
}

/// Which earlier tokens each token waits for (graph/dependencies.h).
void printDependencies(const graph::Dependencies& d) {
  if (!d.learned) {
    std::cout << "\ndependencies: not in this manifest (trained before they were learned): every token waits for "
                 "every earlier one (step by step)\n";
    return;
  }
  std::cout
      << "\ndependencies over " << d.demonstrations
      << " demonstrations: a token waits for the earlier tokens whose entities (its own, its target, its load) it "
         "involves, and for those below marked 'waits'\n";
  if (d.evidence.empty()) {
    std::cout << "  no demonstration shows a token waiting for, or starting before the end of, a token it shares no "
                 "entity with\n";
    return;
  }
  std::cout << "  " << std::left << std::setw(20) << "token" << std::setw(20) << "after" << std::right << std::setw(14)
            << "shown waiting" << std::setw(15) << "started early"
            << "  decision\n";
  for (const graph::WaitEvidence& e : d.evidence)
    std::cout << "  " << std::left << std::setw(20) << e.token << std::setw(20) << e.after << std::right
              << std::setw(14) << e.shown_waiting << std::setw(15) << e.started_early << "  "
              << (e.waits() ? "waits" : "does not wait") << "\n";
}

int runInspect(const std::vector<std::string>& argv) {
  Args args(argv, {}, {"--loss"});
  const std::string dir = args.positional(0, "MODELDIR");
  args.expectAtMostPositional(1);
  // The loader every user of a model goes through: every file is read and verified.
  const pipeline::Model loaded = pipeline::loadModel(dir);
  const tgn::SequenceModel& model = loaded.sequence;
  const tgn::ModelInfo& info = model.info();
  const task::TaskSpec& spec = model.spec();
  const auto name = [&](int i) { return spec.entities.at(static_cast<size_t>(i)).name; };
  const tgn::TrainOptions& o = info.options;

  std::cout << dir << ": " << info.format << ", variant '" << tgn::toString(info.variant) << "', task '" << spec.name
            << "'\n";
  std::cout << "  entities:   ";
  for (const auto& e : spec.entities) std::cout << " " << e.name;
  std::cout << "\n  vocabulary: ";
  for (const auto& a : info.vocabulary) std::cout << " " << a;
  std::cout << "\n  network:     " << o.gat_layers << " GAT layers x " << o.heads << " heads x " << o.head_channels
            << " channels, GRU " << o.gru_layers << " x " << o.gru_hidden << ", identity embedding "
            << (info.plan.identity_embedding ? "on (" + std::to_string(o.identity_dim) + ")" : std::string("off"))
            << ", dropout " << o.dropout << "\n";
  std::cout << "  training:    seed " << o.seed << ", Adam lr " << o.learning_rate << ", " << o.batch_demos
            << " demos per batch, plateau " << o.plateau_patience << " epochs / " << o.plateau_delta << "\n";
  if (!info.history.empty()) {
    const auto& last = info.history.back();
    std::cout << "  result:      " << last.epoch << " epochs (" << info.stop_reason << "), loss " << last.loss << ", "
              << (info.variant == tgn::Variant::Gnn ? "frame label" : "step") << " accuracy " << last.step_accuracy
              << ", " << last.seconds << " s\n";
  }
  const tgn::StepRules& r = info.plan.step_rules;
  std::cout << "  step rules:  "
            << (r.any() ? std::string(r.exclusive_targets ? "a target at most once per step" : "") +
                              (r.exclusive_targets && r.step_size > 0 ? ", " : "") +
                              (r.step_size > 0 ? std::to_string(r.step_size) + " acting entities per step" : "") +
                              " (decoded jointly when the entities' own argmax breaks them)"
                        : std::string("none (each entity decoded on its own)"))
            << "\n";
  if (info.variant == tgn::Variant::Scene) {
    const auto on = [](bool b) { return b ? "yes" : "no"; };
    const tgn::TrainingPlan& plan = info.plan;
    std::string without;
    for (tgn::Rule rule : o.without) without += std::string(without.empty() ? "" : ",") + tgn::toString(rule);
    std::cout << "  plan:        fixed order " << on(plan.fixed_order) << " (" << plan.slips
              << " slips), relative features " << on(plan.relative_features) << ", names or the scene "
              << on(plan.names_or_scene) << ", name groups shuffled " << plan.name_groups.size() << ", token by token "
              << on(plan.token_by_token) << ", parked entities out of the ranks " << on(plan.parked_out_of_ranks)
              << ", ensemble of " << plan.ensemble << (plan.ensemble == 1 ? " network" : " networks")
              << (without.empty() ? std::string() : "; asked --without " + without) << " (docs/tgn.md)\n";
    std::cout << "  end scene:   " << endSceneText(plan.end_scene) << "\n";
  }
  std::cout << "  transfer:    runs on " << model.transfer().text() << "\n";
  const auto join = [](const auto& items) {
    std::string out;
    for (const auto& i : items) {
      std::ostringstream s;
      s << i;
      out += (out.empty() ? "" : ", ") + s.str();
    }
    return "[" + out + "]";
  };
  const task::TaskFingerprint& f = info.fingerprint;
  std::cout << "  task fingerprint " << f.digest().substr(0, 16) << ": token types " << join(f.token_types)
            << ", steps per demonstration " << join(f.step_counts) << ", goal conditions " << join(f.goal_conditions)
            << ", " << f.demonstrations << " demonstrations\n";
  std::cout << "  files (verified):";
  for (const auto& [name, d] : info.files) std::cout << " " << name << " (" << d.bytes << " bytes)";
  std::cout << "\n";
  if (loaded.primitives)
    std::cout << "  primitives:  " << loaded.primitives->primitives().size() << " motion primitives\n";
  std::cout << "  normalisation: x' = (x - " << info.mean[0] << ") / " << info.std[0] << ", y' = (y - " << info.mean[1]
            << ") / " << info.std[1] << "  (metres)\n";

  const graph::RefinedGraph& g = info.refined;
  std::cout << "\nspectral refinement over " << g.demonstrations << " demonstrations: " << g.clusters << " cluster(s)";
  if (g.clusters > 1) {
    for (int c = 0; c < g.clusters; ++c) {
      std::cout << (c ? " |" : ":");
      for (size_t i = 0; i < g.cluster.size(); ++i)
        if (g.cluster[i] == c) std::cout << " " << name(static_cast<int>(i));
    }
  }
  std::cout << "\n  eigenvalues of the normalised Laplacian:";
  for (Eigen::Index i = 0; i < g.eigenvalues.size(); ++i)
    std::cout << " " << std::fixed << std::setprecision(3) << g.eigenvalues(i);
  std::cout.unsetf(std::ios::floatfield);
  std::cout << "\n  " << std::left << std::setw(16) << "edge" << std::right << std::setw(10) << "frequency"
            << std::setw(8) << "demos" << std::setw(9) << "support"
            << "  decision\n";
  for (const auto& s : g.edges) {
    std::cout << "  " << std::left << std::setw(16) << (name(s.edge.source) + " -> " + name(s.edge.target))
              << std::right << std::setw(10) << s.frequency << std::setw(8) << s.demos << std::setw(9) << std::fixed
              << std::setprecision(2) << s.support << "  " << graph::toString(s.decision) << "\n";
    std::cout.unsetf(std::ios::floatfield);
  }
  std::cout << "E' (" << g.kept.size() << " edges):";
  for (const auto& e : g.kept) std::cout << " " << name(e.source) << "->" << name(e.target);
  std::cout << "\nthe network attends over " << info.plan.attention_edges.size() << " directed edges"
            << (info.variant == tgn::Variant::Paper   ? " (E', both directions, plus self-loops)"
                : info.variant == tgn::Variant::Scene ? " (E' lifted to entity kinds, both directions, plus self-loops)"
                                                      : " (every pair, plus self-loops)")
            << "\n";
  printDependencies(info.dependencies);
  if (args.has("--loss")) {
    std::cout << "\nepoch,loss,step_accuracy,seconds\n";
    for (const auto& r : info.history)
      std::cout << r.epoch << "," << r.loss << "," << r.step_accuracy << "," << r.seconds << "\n";
  }
  return 0;
}

DDACE_COMMAND(
    {"inspect", "ddace inspect MODELDIR [--loss]",
     "check every file of a model directory (digests, task fingerprint) and print its task, network, training "
     "result, refined edge set E' and which earlier tokens each token waits for",
     runInspect});

}  // namespace
}  // namespace ddace::cli
