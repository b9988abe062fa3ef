// The closing section of docs/results.md written by `ddace table`: how to read the
// numbers. It holds no number: every figure in that file comes from the run itself.
#pragma once

#define DDACE_RESULTS_DISCUSSION                                                                                \
  "- **Two networks, one name each.** `paper` is the paper's network (GAT over E', mean pooling, GRU, one "     \
  "linear output slot per entity); `scene` (the default, docs/tgn.md) sees no absolute position: distances "    \
  "and nearness ranks on the attention edges, entity kinds, per-entity heads and a pointer over the candidate " \
  "targets. On the paper's four families the step order is fixed and both only have to count keyframes; the "   \
  "scene-dependent families (fetch, nearest_goal, queue, deliver) are where they differ: the paper's network "  \
  "has no path from \"which robot is nearest\" to its output slots. The default also keeps the step rules "     \
  "its training demonstrations kept (docs/tgn.md, \"Step rules\": a target at most once per step, a fixed "     \
  "number of acting entities) by decoding a step jointly when the entities' own argmax breaks them; where a "   \
  "step's targets exclude each other it chooses them token by token, each conditioned on those chosen "         \
  "(nearest_goal), and an entity that arrived where another stands is no rival in the nearness ranks "          \
  "(queue; docs/tgn.md, \"Token by token\", \"Parked entities\"). `ddace eval` prints the first differing "     \
  "step of a failed trial.\n"                                                                                   \
  "- **Imperfect demonstrations.** A mislabelled token is a labelling slip: the demonstrations of a fixed "     \
  "order still have the same steps but for one token in a few of them (at most one in ten), and training "      \
  "reads them as a fixed order (docs/tgn.md, \"Fixed order\"; `ddace validate` lists the slips); E' drops "     \
  "the slipped edges as rare.\n"                                                                                \
  "- **Where E' matters.** The E' rules column counts the observed interaction edges each refinement rule "     \
  "decided. On clean demonstrations of a fixed-order family every observed edge recurs, so the rule "           \
  "\"recurs\" decides all of them and E' is exactly the demonstrated edge set; the ablation (`full-graph`) "    \
  "then differs from DDACE only by extra edges between entities that never interact, which attention learns "   \
  "to ignore: where its rows equal the paper network's, E' did not matter. The cluster rule and the rare rule " \
  "only have work where edges occur in some demonstrations and not others: mislabelled tokens (the imperfect "  \
  "rows, dropped as rare) and the scene-dependent families, whose edges depend on the configuration (R1 -> G2 " \
  "in one demonstration, R3 -> G2 in the next: kept by the cluster rule). The default network lifts E' to "     \
  "entity kinds (every pair whose kinds are those of a kept edge), so for it E' only decides which kinds of "   \
  "entity attend to each other; the table has no ablation of E' for the default network, so it does not show "  \
  "that E' changes any of its decisions. Where the counts of the cluster and rare rules are zero, E' decided "  \
  "nothing beyond the demonstrated edge set.\n"                                                                 \
  "- **Human-timed demonstrations.** Label onsets up to 0.4 s apart within a step are merged by step "          \
  "grouping (a token joins its step while every token of it still runs) before anything is learned, so the "    \
  "sequence model sees the "                                                                                    \
  "same steps as from clean data; what remains is the 2 mm position noise.\n"                                   \
  "- **Closed loop.** The ideal rows end every motion on its target, as the paper's evaluation; the "           \
  "closed-loop rows drive the same models' paths with the path follower's control law, so robots stop "         \
  "within the arrival radius and the next decision and path start from there. The network treats entities "     \
  "within contact plus the arrival radius of each other as at one place (docs/tgn.md, \"Entities at one "       \
  "place\"), which is "                                                                                         \
  "what keeps such stops from changing a decision; where a closed-loop OSR is below the ideal one, a stop "     \
  "short of a target did.\n"                                                                                    \
  "- **GNN baseline.** It is trained as seriously as DDACE — the same encoder, GRU, optimiser and "           \
  "plateau rule, to its loss plateau (epochs column) — but on every frame, to predict the next "              \
  "positions and labels, and it rolls out its own trajectories: small errors in the predicted "                 \
  "displacements compound over hundreds of frames, and a label switch predicted a few frames early or "         \
  "late splits or merges steps. Its GCR stays low even where the label sequence is right, because the "         \
  "rolled-out robots drift and stop away from their goals, and its FD is an order of magnitude above the "      \
  "GP primitives'. Differences to the paper's GNN row may come from the frame rate and trajectory length "      \
  "(ours: the generator's 20 Hz rows over the whole task) and the model size, which the paper does not give.\n" \
  "- **LLM.** The paper's LLM baseline needs a hosted language model; it cannot be reproduced offline; its "    \
  "row quotes the paper.\n"                                                                                     \
  "- **Paper column.** The paper's Table 2 for DDACE, DDACE without spectral clustering and the GNN, per "      \
  "task (OSR / SSR / GCR / FD). Our ablation does not reproduce the paper's gap on generated demonstrations "   \
  "(see \"Where E' matters\").\n"
