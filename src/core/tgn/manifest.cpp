#include "manifest.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iomanip>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/sha256.h"
#include "ddace/common/yaml_checker.h"

namespace ddace::tgn {

const char* toString(Variant v) {
  switch (v) {
    case Variant::Scene:
      return "scene";
    case Variant::Paper:
      return "paper";
    case Variant::FullGraph:
      return "full-graph";
    case Variant::Gnn:
      return "gnn";
  }
  return "?";
}

std::vector<Variant> allVariants() {
  return {Variant::Scene, Variant::Paper, Variant::FullGraph, Variant::Gnn};
}

Variant variantFromString(const std::string& name) {
  std::string names;
  for (Variant v : allVariants()) {
    if (name == toString(v)) return v;
    names += std::string(names.empty() ? "" : ", ") + toString(v);
  }
  throw Error("variant '" + name + "' is not one of " + names);
}

namespace {

const std::pair<Rule, const char*> kRuleNames[] = {
    {Rule::Relative, "relative"},
    {Rule::FixedOrder, "fixed-order"},
    {Rule::ShuffledNames, "shuffled-names"},
    {Rule::TokenByToken, "token-by-token"},
    {Rule::Parked, "parked"},
    {Rule::Ensemble, "ensemble"},
    {Rule::EndScene, "end-scene"},
    {Rule::NextTargets, "next-targets"},
};

}  // namespace

const char* toString(Rule r) {
  for (const auto& [rule, name] : kRuleNames)
    if (rule == r) return name;
  return "?";
}

std::vector<Rule> allRules() {
  std::vector<Rule> out;
  for (const auto& [rule, name] : kRuleNames) out.push_back(rule);
  return out;
}

Rule ruleFromString(const std::string& name) {
  std::string names;
  for (const auto& [rule, n] : kRuleNames) {
    if (name == n) return rule;
    names += std::string(names.empty() ? "" : ", ") + n;
  }
  throw Error("'" + name + "' is not a learning rule (" + names + ")");
}

std::set<Rule> rulesFromList(const std::string& list) {
  std::set<Rule> out;
  for (size_t from = 0; !list.empty() && from <= list.size();) {
    const size_t comma = std::min(list.find(',', from), list.size());
    out.insert(ruleFromString(list.substr(from, comma - from)));
    from = comma + 1;
  }
  return out;
}

void TrainOptions::validate() const {
  auto bad = [](const std::string& what) { throw Error("train option " + what); };
  if (max_epochs < 1) bad("max_epochs: must be at least 1");
  if (heads < 1 || head_channels < 1) bad("heads/head_channels: must be at least 1");
  if (gat_layers < 1 || gru_layers < 1 || gru_hidden < 1) bad("gat_layers/gru_layers/gru_hidden: must be at least 1");
  if (identity_dim < 1) bad("identity_dim: must be at least 1");
  if (head_hidden < 1) bad("head_hidden: must be at least 1");
  if (!(weight_decay >= 0 && std::isfinite(weight_decay))) bad("weight_decay: must be a non-negative number");
  if (!(dropout >= 0 && dropout < 1)) bad("dropout: must be in [0, 1)");
  if (!(learning_rate > 0 && std::isfinite(learning_rate))) bad("learning_rate: must be positive");
  if (batch_demos < 1) bad("batch_demos: must be at least 1");
  if (plateau_patience < 1) bad("plateau_patience: must be at least 1");
  if (!(plateau_delta >= 0)) bad("plateau_delta: must be non-negative");
  if (threads < 1 || threads > kMaxThreads) bad("threads: must be in 1.." + std::to_string(kMaxThreads));
  // Upper bounds too: a manifest is outside input, and these sizes are allocated from.
  if (max_epochs > 1000000) bad("max_epochs: must be at most 1000000");
  if (heads > 64 || head_channels > 1024) bad("heads/head_channels: must be at most 64/1024");
  if (gat_layers > 16 || gru_layers > 16 || gru_hidden > 4096)
    bad("gat_layers/gru_layers/gru_hidden: must be at most 16/16/4096");
  if (identity_dim > 1024 || head_hidden > 4096) bad("identity_dim/head_hidden: must be at most 1024/4096");
  if (batch_demos > 100000 || plateau_patience > 100000) bad("batch_demos/plateau_patience: must be at most 100000");
}

namespace files {

FileDigest digestOf(const std::string& bytes) {
  return {bytes.size(), sha256Hex(bytes)};
}

void verifyDigest(const std::string& path, const std::string& bytes, const FileDigest& expected,
                  const std::string& manifest) {
  if (bytes.size() != expected.bytes)
    throw Error(Diagnostic{path, 0, 0,
                           "truncated or replaced: " + std::to_string(bytes.size()) + " bytes, " + manifest + " says " +
                               std::to_string(expected.bytes)});
  const std::string actual = sha256Hex(bytes);
  if (actual != expected.sha256)
    throw Error(Diagnostic{path, 0, 0,
                           "edited or corrupted: its SHA-256 " + actual + " is not the " + expected.sha256 + " that " +
                               manifest + " records"});
}

std::string readFile(const std::string& path, uint64_t max_bytes) {
  return readTextFile(path, max_bytes);
}

void writeFile(const std::string& path, const std::string& text) {
  writeTextFile(path, text);
}

namespace {

using EntityName = std::function<std::string(int)>;

void emitHyperParameters(YAML::Emitter& y, const TrainOptions& o) {
  y << YAML::Key << "hyper_parameters" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "max_epochs" << YAML::Value << o.max_epochs;
  y << YAML::Key << "heads" << YAML::Value << o.heads;
  y << YAML::Key << "head_channels" << YAML::Value << o.head_channels;
  y << YAML::Key << "gat_layers" << YAML::Value << o.gat_layers;
  y << YAML::Key << "gru_layers" << YAML::Value << o.gru_layers;
  y << YAML::Key << "gru_hidden" << YAML::Value << o.gru_hidden;
  y << YAML::Key << "identity_embedding" << YAML::Value << o.identity_embedding;
  y << YAML::Key << "identity_dim" << YAML::Value << o.identity_dim;
  y << YAML::Key << "head_hidden" << YAML::Value << o.head_hidden;
  std::vector<std::string> without;
  for (Rule rule : o.without) without.push_back(toString(rule));
  y << YAML::Key << "without" << YAML::Value << YAML::Flow << without;
  y << YAML::Key << "weight_decay" << YAML::Value << o.weight_decay;
  y << YAML::Key << "dropout" << YAML::Value << o.dropout;
  y << YAML::Key << "learning_rate" << YAML::Value << o.learning_rate;
  y << YAML::Key << "batch_demos" << YAML::Value << o.batch_demos;
  y << YAML::Key << "plateau_patience" << YAML::Value << o.plateau_patience;
  y << YAML::Key << "plateau_delta" << YAML::Value << o.plateau_delta;
  y << YAML::Key << "threads" << YAML::Value << o.threads;
  y << YAML::Key << "keep_support" << YAML::Value << o.refinement.keep_support;
  y << YAML::Key << "drop_support" << YAML::Value << o.refinement.drop_support;
  y << YAML::EndMap;
}

void emitNormalisation(YAML::Emitter& y, const ModelInfo& info) {
  y << YAML::Key << "normalisation" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "mean_m" << YAML::Value << YAML::Flow << std::vector<double>{info.mean[0], info.mean[1]};
  y << YAML::Key << "std_m" << YAML::Value << YAML::Flow << std::vector<double>{info.std[0], info.std[1]};
  y << YAML::Key << "delta_std_m" << YAML::Value << YAML::Flow
    << std::vector<double>{info.delta_std[0], info.delta_std[1]};
  y << YAML::Key << "frame_dt_s" << YAML::Value << info.frame_dt_s;
  y << YAML::EndMap;
}

void emitRefinement(YAML::Emitter& y, const graph::RefinedGraph& g, const EntityName& name) {
  y << YAML::Key << "refinement" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "demonstrations" << YAML::Value << g.demonstrations;
  y << YAML::Key << "clusters" << YAML::Value << g.clusters;
  y << YAML::Key << "cluster_of" << YAML::Value << YAML::Flow << YAML::BeginMap;
  for (size_t i = 0; i < g.cluster.size(); ++i)
    y << YAML::Key << name(static_cast<int>(i)) << YAML::Value << g.cluster[i];
  y << YAML::EndMap;
  std::vector<double> eig(g.eigenvalues.data(), g.eigenvalues.data() + g.eigenvalues.size());
  y << YAML::Key << "eigenvalues" << YAML::Value << YAML::Flow << eig;
  y << YAML::Key << "edges" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : g.edges) {
    y << YAML::Flow << YAML::BeginMap;
    y << YAML::Key << "source" << YAML::Value << name(s.edge.source);
    y << YAML::Key << "target" << YAML::Value << name(s.edge.target);
    y << YAML::Key << "frequency" << YAML::Value << s.frequency;
    y << YAML::Key << "demos" << YAML::Value << s.demos;
    y << YAML::Key << "support" << YAML::Value << s.support;
    y << YAML::Key << "decision" << YAML::Value << graph::toString(s.decision);
    y << YAML::EndMap;
  }
  y << YAML::EndSeq;
  y << YAML::EndMap;
}

void emitPlan(YAML::Emitter& y, const TrainingPlan& plan, const EntityName& name) {
  y << YAML::Key << "plan" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "fixed_order" << YAML::Value << plan.fixed_order;
  y << YAML::Key << "slips" << YAML::Value << plan.slips;
  y << YAML::Key << "relative_features" << YAML::Value << plan.relative_features;
  y << YAML::Key << "identity_embedding" << YAML::Value << plan.identity_embedding;
  y << YAML::Key << "names_or_scene" << YAML::Value << plan.names_or_scene;
  y << YAML::Key << "name_groups" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const auto& g : plan.name_groups) {
    std::vector<std::string> names;
    for (int e : g) names.push_back(name(e));
    y << YAML::Flow << names;
  }
  y << YAML::EndSeq;
  y << YAML::Key << "token_by_token" << YAML::Value << plan.token_by_token;
  y << YAML::Key << "parked_out_of_ranks" << YAML::Value << plan.parked_out_of_ranks;
  y << YAML::Key << "ensemble" << YAML::Value << plan.ensemble;
  y << YAML::Key << "step_rules" << YAML::Value << YAML::Flow << YAML::BeginMap;
  y << YAML::Key << "exclusive_targets" << YAML::Value << plan.step_rules.exclusive_targets;
  y << YAML::Key << "step_size" << YAML::Value << plan.step_rules.step_size;
  y << YAML::Key << "load_actions" << YAML::Value << YAML::Flow << plan.step_rules.load_actions;
  y << YAML::EndMap;
  y << YAML::Key << "end_scene" << YAML::Value << YAML::Flow << YAML::BeginMap;
  y << YAML::Key << "telling" << YAML::Value << plan.end_scene.telling;
  y << YAML::Key << "counts" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const EndCount& c : plan.end_scene.counts)
    y << YAML::Flow << YAML::BeginSeq << c.kind << c.with << c.count << YAML::EndSeq;
  y << YAML::EndSeq;
  y << YAML::EndMap;
  y << YAML::Key << "next_targets" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const NextTarget& t : plan.next_targets)
    y << YAML::Flow << YAML::BeginSeq << t.kind << t.after << t.target << YAML::EndSeq;
  y << YAML::EndSeq;
  y << YAML::Key << "attention_edges" << YAML::Value << YAML::BeginSeq;
  for (const auto& e : plan.attention_edges)
    y << YAML::Flow << std::vector<std::string>{name(e.source), name(e.target)};
  y << YAML::EndSeq;
  y << YAML::EndMap;
}

}  // namespace

std::string manifestText(const ModelInfo& info, const task::TaskSpec& spec,
                         const std::map<std::string, FileDigest>& files) {
  const EntityName name = [&](int i) { return spec.entities.at(static_cast<size_t>(i)).name; };
  const TrainOptions& o = info.options;
  YAML::Emitter y;
  y.SetDoublePrecision(17);
  y << YAML::BeginMap;
  y << YAML::Key << "format" << YAML::Value << kModelFormat;
  y << YAML::Key << "variant" << YAML::Value << toString(info.variant);
  y << YAML::Key << "seed" << YAML::Value << o.seed;
  y << YAML::Key << "task" << YAML::Value << kTask;
  y << YAML::Key << "files" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, d] : files) {
    y << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
    y << YAML::Key << "bytes" << YAML::Value << d.bytes;
    y << YAML::Key << "sha256" << YAML::Value << d.sha256;
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
  y << YAML::Key << "task_fingerprint" << YAML::Value;
  task::emitFingerprint(y, info.fingerprint);
  y << YAML::Key << "epochs" << YAML::Value << info.history.size();
  y << YAML::Key << "stop_reason" << YAML::Value << info.stop_reason;
  y << YAML::Key << "entities" << YAML::Value << YAML::Flow << spec.entityNames();
  y << YAML::Key << "vocabulary" << YAML::Value << YAML::Flow << info.vocabulary;
  emitHyperParameters(y, info.options);
  emitNormalisation(y, info);
  emitRefinement(y, info.refined, name);
  emitPlan(y, info.plan, name);
  y << YAML::Key << "dependencies" << YAML::Value;
  graph::emitDependencies(y, info.dependencies);
  y << YAML::Key << "transfer" << YAML::Value << transferOf(info, spec).text();
  y << YAML::EndMap;
  const std::string body =
      std::string("# ddace model manifest (") + kModelFormat +
      "): written by `ddace train`, read by `ddace inspect` and the sequence node.\n"
      "# hyper_parameters: what the user asked; plan: what the demonstrations decided (docs/tgn.md).\n"
      "# E' is refinement.edges with a 'kept' decision; plan.attention_edges is what the network\n"
      "# attends over (paper: E'; scene: E' lifted to entity kinds; full-graph, gnn: every pair),\n"
      "# made symmetric. files: size and SHA-256 of each file; the last line is the SHA-256 of\n"
      "# everything before it. Do not edit: any change is refused.\n" +
      y.c_str() + "\n";
  return body + kManifestDigestKey + ": " + sha256Hex(body) + "\n";
}

namespace {

/// The manifest's fields through one YamlChecker (file:line:column diagnostics, the one
/// YAML reader style of the project). A manifest is written by `ddace train` and sealed by
/// its own digest, so the first problem is thrown at once rather than collected.
class Reader {
 public:
  explicit Reader(const std::string& path) : c_(path) {}

  YAML::Node parse(const std::string& text) {
    const YAML::Node root = c_.parse(text);
    c_.throwIfErrors();
    return root;
  }
  [[noreturn]] void fail(const YAML::Node& node, const std::string& message) {
    c_.error(node, message);
    throwNow();
  }
  /// `map[key]`; "missing key" when `map` has none.
  YAML::Node need(const YAML::Node& map, const std::string& key) {
    if (!map.IsMap()) fail(map, "expected a mapping with the key '" + key + "'");
    const YAML::Node n = c_.required(map, key);  // a key without a value is missing too
    if (!n) throwNow();
    return n;
  }
  std::string textAt(const YAML::Node& node, const std::string& what) {
    std::string s;
    if (!c_.scalar(node, what, s)) throwNow();
    return s;
  }
  std::string text(const YAML::Node& map, const char* key) {
    return textAt(need(map, key), std::string("'") + key + "'");
  }
  bool boolean(const YAML::Node& map, const char* key) {
    bool b = false;
    if (!c_.boolean(need(map, key), std::string("'") + key + "'", b)) throwNow();
    return b;
  }
  double numberAt(const YAML::Node& node, const std::string& what) {
    double v = 0;
    if (!c_.number(node, what, v)) throwNow();
    return v;
  }
  double numberIn(const YAML::Node& node, const std::string& what, double lo, double hi) {
    double v = 0;
    if (!c_.number(node, what, lo, hi, v)) throwNow();
    return v;
  }
  double number(const YAML::Node& map, const char* key) {
    return numberAt(need(map, key), std::string("'") + key + "'");
  }
  /// A whole number in [lo, hi], checked and worded as every YAML reader does
  /// ("<what> must be an integer in lo..hi (got x)").
  int64_t integerAt(const YAML::Node& node, const std::string& what, int64_t lo, int64_t hi) {
    long v = 0;
    if (!c_.integer(node, what, static_cast<long>(lo), static_cast<long>(hi), v)) throwNow();
    return v;
  }
  int integer(const YAML::Node& map, const char* key) {
    return static_cast<int>(integerAt(need(map, key), std::string("'") + key + "'", std::numeric_limits<int>::min(),
                                      std::numeric_limits<int>::max()));
  }
  /// A non-negative 64-bit whole number (seeds, byte counts).
  uint64_t count(const YAML::Node& map, const char* key) {
    const YAML::Node n = need(map, key);
    const std::string s = textAt(n, std::string("'") + key + "'");
    const bool ok =
        !s.empty() && s.size() <= 20 && std::all_of(s.begin(), s.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
    errno = 0;
    const unsigned long long v = ok ? std::strtoull(s.c_str(), nullptr, 10) : 0;
    if (!ok || errno == ERANGE) fail(n, std::string("'") + key + "': '" + s + "' is not a whole number >= 0");
    return v;
  }
  YAML::Node sequence(const YAML::Node& map, const char* key) {
    const YAML::Node n = need(map, key);
    if (!n.IsSequence()) fail(n, std::string("'") + key + "' must be a list");
    return n;
  }
  std::vector<std::string> texts(const YAML::Node& map, const char* key) {
    std::vector<std::string> out;
    for (const YAML::Node& n : sequence(map, key)) out.push_back(textAt(n, std::string("an item of '") + key + "'"));
    return out;
  }
  std::vector<double> numbers(const YAML::Node& map, const char* key) {
    std::vector<double> out;
    for (const YAML::Node& n : sequence(map, key)) out.push_back(numberAt(n, std::string("an item of '") + key + "'"));
    return out;
  }
  /// The index in `spec` of the entity named by `node`.
  int entity(const YAML::Node& node, const task::TaskSpec& spec) {
    const std::string name = textAt(node, "an entity name");
    const int i = spec.entityIndex(name);
    if (i < 0) fail(node, "unknown entity '" + name + "' (not in task.yaml)");
    return i;
  }
  graph::Decision decision(const YAML::Node& node) {
    const std::string s = textAt(node, "'decision'");
    for (auto d : {graph::Decision::KeptRecurrent, graph::Decision::KeptSameCluster, graph::Decision::DroppedRare,
                   graph::Decision::DroppedCrossCluster})
      if (s == graph::toString(d)) return d;
    fail(node, "unknown edge decision '" + s + "'");
  }

 private:
  [[noreturn]] void throwNow() {
    c_.throwIfErrors();
    throw Error(c_.file() + ": unreadable manifest");  // not reached: a failed check records an error
  }
  YamlChecker c_;
};

/// The manifest's YAML after the format check and the check of its own digest.
YAML::Node checkedRoot(Reader& r, const std::string& text, const std::string& path) {
  const YAML::Node root = r.parse(text);
  if (!root.IsMap()) throw Error(Diagnostic{path, 1, 1, "not a model manifest (expected a YAML map)"});
  const YAML::Node format_node = r.need(root, "format");
  const std::string format = r.textAt(format_node, "'format'");
  // "ddace-model/N": an older N is refused with what it lacks, a newer one as such.
  const std::string prefix = "ddace-model/";
  const std::string own = std::string(kModelFormat).substr(prefix.size());
  const bool readable = format == kModelFormat;
  if (format.rfind(prefix, 0) == 0 && !readable) {
    const std::string version = format.substr(prefix.size());
    const bool numeric = !version.empty() && version.size() <= 6 &&
                         std::all_of(version.begin(), version.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (numeric && std::stoi(version) < std::stoi(own)) {
      const int v = std::stoi(version);
      const std::string lacks = std::string(
                                    "its scene features read a move as going to the nearest entity ahead, not "
                                    "to the one it stopped at") +
                                (v < 16 ? ", its plan has no end scene (END counted the steps)" : "") +
                                (v < 15 ? ", its motion primitives are keyed by name only" : "") +
                                (v < 14 ? ", token by token it chose the acting entities' targets only, not who "
                                          "acts, and it ranked a parked entity among the free ones"
                                        : "") +
                                (v < 13 ? ", the scene network's relational basis changed" : "") +
                                (v < 11 ? ", its plan has no ensemble" : "") +
                                (v < 10 ? ", its step rules counted a carried load as an actor" : "") +
                                (v < 9 ? ", its manifest records no training plan" : "") +
                                (v < 4 ? ", the step rules learned from the demonstrations" : "") +
                                (v < 3 ? ", and its files are not bound by digests to the model and its task" : "");
      r.fail(format_node, "format '" + format + "' is an older model format than " + kModelFormat + " (" + lacks +
                              "): retrain the model (ddace train)");
    }
    if (numeric)
      r.fail(format_node, "format '" + format + "' is newer than " + kModelFormat + ", the newest this ddace reads");
  }
  if (!readable) r.fail(format_node, "format '" + format + "' is not " + kModelFormat);
  // The digest line must be the last line; the digest covers every byte before it.
  const std::string key = std::string("\n") + kManifestDigestKey + ": ";
  const size_t at = text.rfind(key);
  const size_t digest_begin = at == std::string::npos ? 0 : at + key.size();
  if (at == std::string::npos || text.size() != digest_begin + 65 || text.back() != '\n' ||
      !isSha256Hex(std::string_view(text).substr(digest_begin, 64)))
    throw Error(Diagnostic{path, 0, 0,
                           std::string("no '") + kManifestDigestKey +
                               ": <64 hex digits>' as the last line: the manifest was cut or edited"});
  const std::string body = text.substr(0, at + 1), stored = text.substr(digest_begin, 64);
  if (sha256Hex(body) != stored)
    throw Error(Diagnostic{path, 0, 0,
                           std::string("edited or corrupted: its content does not match its own digest (") +
                               kManifestDigestKey + "); restore the file or retrain the model"});
  return root;
}

std::map<std::string, FileDigest> parseFiles(Reader& r, const YAML::Node& root) {
  const YAML::Node files = r.need(root, "files");
  if (!files.IsMap()) r.fail(files, "'files' must map file names to {bytes, sha256}");
  std::map<std::string, FileDigest> out;
  for (auto it = files.begin(); it != files.end(); ++it) {
    const std::string name = r.textAt(it->first, "a file name");
    if (name != kTask && name != kWeights && name != kLoss && name != "primitives.yaml")
      r.fail(it->first, "'files' names '" + name + "', not a file of a model directory");
    FileDigest d;
    d.bytes = r.count(it->second, "bytes");
    d.sha256 = r.text(it->second, "sha256");
    if (!isSha256Hex(d.sha256)) r.fail(it->second["sha256"], name + ": sha256 is not 64 hex digits");
    out[name] = d;
  }
  for (const char* required : {kTask, kWeights, kLoss})
    if (!out.count(required)) r.fail(files, std::string("'files' has no digest of ") + required);
  return out;
}

/// yaml-cpp's own exceptions (a subscript of a node of another kind) as a diagnostic.
Error yamlError(const std::string& path, const YAML::Exception& e) {
  return Error(
      Diagnostic{path, e.mark.is_null() ? 0 : e.mark.line + 1, e.mark.is_null() ? 0 : e.mark.column + 1, e.msg});
}

/// The vocabulary, in the action head's class order.
void parseVocabulary(Reader& r, const YAML::Node& root, ModelInfo& info) {
  info.vocabulary = r.texts(root, "vocabulary");
  {
    // The vocabulary's order is the action head's class order: it must be the training
    // directory's, whose sorted set the fingerprint records.
    std::vector<std::string> sorted = info.vocabulary;
    std::sort(sorted.begin(), sorted.end());
    if (info.vocabulary.empty() || sorted != info.fingerprint.vocabulary ||
        std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
      r.fail(root["vocabulary"], "vocabulary does not match task_fingerprint.vocabulary");
  }
}

/// hyper_parameters: what the user asked (TrainOptions), validated as training validates it.
void parseHyperParameters(Reader& r, const YAML::Node& root, TrainOptions& o) {
  const YAML::Node hp = r.need(root, "hyper_parameters");
  o.max_epochs = r.integer(hp, "max_epochs");
  o.heads = r.integer(hp, "heads");
  o.head_channels = r.integer(hp, "head_channels");
  o.gat_layers = r.integer(hp, "gat_layers");
  o.gru_layers = r.integer(hp, "gru_layers");
  o.gru_hidden = r.integer(hp, "gru_hidden");
  o.identity_embedding = r.boolean(hp, "identity_embedding");
  o.identity_dim = r.integer(hp, "identity_dim");
  o.head_hidden = r.integer(hp, "head_hidden");
  for (const YAML::Node& w : r.sequence(hp, "without")) {
    try {
      o.without.insert(ruleFromString(r.textAt(w, "an item of 'without'")));
    } catch (const Error& e) {
      r.fail(w, std::string("without: ") + e.what());
    }
  }
  o.weight_decay = r.number(hp, "weight_decay");
  o.dropout = r.number(hp, "dropout");
  o.learning_rate = r.number(hp, "learning_rate");
  o.batch_demos = r.integer(hp, "batch_demos");
  o.plateau_patience = r.integer(hp, "plateau_patience");
  o.plateau_delta = r.number(hp, "plateau_delta");
  o.threads = r.integer(hp, "threads");
  o.refinement.keep_support = r.number(hp, "keep_support");
  o.refinement.drop_support = r.number(hp, "drop_support");
  o.refinement.seed = o.seed;
  try {
    o.validate();
  } catch (const Error& e) {
    r.fail(hp, e.what());
  }
}

void parseNormalisation(Reader& r, const YAML::Node& root, ModelInfo& info) {
  const YAML::Node norm = r.need(root, "normalisation");
  const auto pair = [&](const char* key, double* out, bool positive) {
    const auto v = r.numbers(norm, key);
    if (v.size() != 2 || (positive && (v[0] <= 0 || v[1] <= 0)))
      r.fail(norm[key], std::string(key) + " must be two finite numbers" + (positive ? " > 0" : ""));
    out[0] = v[0];
    out[1] = v[1];
  };
  pair("mean_m", info.mean, false);
  pair("std_m", info.std, true);
  pair("delta_std_m", info.delta_std, true);
  info.frame_dt_s = r.number(norm, "frame_dt_s");
  if (!(info.frame_dt_s > 0 && info.frame_dt_s <= 10))
    r.fail(norm["frame_dt_s"], "frame_dt_s must be in (0, 10] seconds");
}

/// The refinement: clusters, eigenvalues and every edge's statistics and decision.
graph::RefinedGraph parseRefinement(Reader& r, const YAML::Node& root, const task::TaskSpec& spec) {
  const YAML::Node ref = r.need(root, "refinement");
  graph::RefinedGraph g;
  g.nodes = static_cast<int>(spec.entities.size());
  g.demonstrations = static_cast<int>(
      r.integerAt(r.need(ref, "demonstrations"), "refinement: demonstrations", 1, task::kMaxFingerprintCount));
  g.clusters =
      static_cast<int>(r.integerAt(r.need(ref, "clusters"), "refinement: clusters (at most the entities)", 1, g.nodes));
  g.cluster.assign(static_cast<size_t>(g.nodes), 0);
  const YAML::Node cof = r.need(ref, "cluster_of");
  if (!cof.IsMap()) r.fail(cof, "'cluster_of' must map entity names to cluster indices");
  for (auto it = cof.begin(); it != cof.end(); ++it)
    g.cluster[static_cast<size_t>(r.entity(it->first, spec))] =
        static_cast<int>(r.integerAt(it->second, "a cluster index (below clusters)", 0, g.clusters - 1));
  const auto eig = r.numbers(ref, "eigenvalues");
  if (eig.size() > static_cast<size_t>(g.nodes)) r.fail(ref["eigenvalues"], "more eigenvalues than entities");
  g.eigenvalues = Eigen::Map<const Eigen::VectorXd>(eig.data(), static_cast<Eigen::Index>(eig.size()));
  for (const YAML::Node& e : r.sequence(ref, "edges")) {
    graph::EdgeStats s;
    s.edge = {r.entity(r.need(e, "source"), spec), r.entity(r.need(e, "target"), spec)};
    s.frequency = static_cast<int>(
        r.integerAt(r.need(e, "frequency"), "an edge's frequency", 0, std::numeric_limits<int>::max()));
    s.demos = static_cast<int>(
        r.integerAt(r.need(e, "demos"), "an edge's demos (at most demonstrations)", 0, g.demonstrations));
    s.support = r.numberIn(r.need(e, "support"), "an edge's support", 0, 1);
    s.decision = r.decision(r.need(e, "decision"));
    g.edges.push_back(s);
    if (graph::isKept(s.decision)) g.kept.push_back(s.edge);
  }
  return g;
}

/// The training plan, checked for consistency with the options (plan_check.cpp).
TrainingPlan parsePlan(Reader& r, const YAML::Node& root, const task::TaskSpec& spec, const ModelInfo& info) {
  const YAML::Node pn = r.need(root, "plan");
  TrainingPlan plan;
  const int n = static_cast<int>(spec.entities.size());
  plan.fixed_order = r.boolean(pn, "fixed_order");
  plan.slips = static_cast<int>(
      r.integerAt(r.need(pn, "slips"), "plan: slips (at most the demonstrations)", 0, info.refined.demonstrations));
  plan.relative_features = r.boolean(pn, "relative_features");
  plan.identity_embedding = r.boolean(pn, "identity_embedding");
  plan.names_or_scene = r.boolean(pn, "names_or_scene");
  for (const YAML::Node& group : r.sequence(pn, "name_groups")) {
    if (!group.IsSequence() || group.size() < 2 || group.size() > spec.entities.size())
      r.fail(group, "a name group is a list of two or more entity names");
    std::vector<int> members;
    for (const YAML::Node& e : group) members.push_back(r.entity(e, spec));
    plan.name_groups.push_back(members);
  }
  plan.token_by_token = r.boolean(pn, "token_by_token");
  plan.parked_out_of_ranks = r.boolean(pn, "parked_out_of_ranks");
  plan.ensemble = static_cast<int>(
      r.integerAt(r.need(pn, "ensemble"), "plan: ensemble (networks, at most " + std::to_string(kMaxEnsemble) + ")", 1,
                  kMaxEnsemble));
  {
    const YAML::Node rules = r.need(pn, "step_rules");
    plan.step_rules.exclusive_targets = r.boolean(rules, "exclusive_targets");
    plan.step_rules.step_size =
        static_cast<int>(r.integerAt(r.need(rules, "step_size"), "step_rules: step_size (at most the entities)", 0, n));
    plan.step_rules.load_actions = r.texts(rules, "load_actions");
    for (const std::string& a : plan.step_rules.load_actions)
      if (std::find(info.vocabulary.begin(), info.vocabulary.end(), a) == info.vocabulary.end())
        r.fail(rules, "step_rules: load_actions names '" + a + "', not an action of the vocabulary");
  }
  {
    const YAML::Node end = r.need(pn, "end_scene");
    plan.end_scene.telling = r.boolean(end, "telling");
    std::set<std::string> kinds;
    for (const auto& e : spec.entities) kinds.insert(kindKey(e));
    for (const YAML::Node& c : r.sequence(end, "counts")) {
      if (!c.IsSequence() || c.size() != 3) r.fail(c, "an end scene count is [KIND, WITH KIND, COUNT]");
      EndCount count{r.textAt(c[0], "end scene: kind"), r.textAt(c[1], "end scene: with kind"), 0};
      for (const std::string* k : {&count.kind, &count.with})
        if (!kinds.count(*k)) r.fail(c, "end scene: '" + *k + "' is no kind of the task's entities");
      count.count = static_cast<int>(r.integerAt(c[2], "end scene: count (at least 1, at most the entities)", 1, n));
      plan.end_scene.counts.push_back(count);
    }
  }
  if (pn["next_targets"]) {  // absent in a manifest written before the rule: no such rule
    std::set<std::string> kinds;
    for (const auto& e : spec.entities) kinds.insert(kindKey(e));
    for (const YAML::Node& t : r.sequence(pn, "next_targets")) {
      if (!t.IsSequence() || t.size() != 3)
        r.fail(t, "a next target is [KIND, KIND ITS LAST MOVE WENT TO, TARGET KIND]");
      NextTarget next{r.textAt(t[0], "next target: kind"), r.textAt(t[1], "next target: after"),
                      r.textAt(t[2], "next target: target kind")};
      if (!kinds.count(next.kind)) r.fail(t, "next target: '" + next.kind + "' is no kind of the task's entities");
      if (next.after != "none" && !kinds.count(next.after))
        r.fail(t, "next target: '" + next.after + "' is neither 'none' nor a kind of the task's entities");
      if (next.target != "none" && !kinds.count(next.target))
        r.fail(t, "next target: '" + next.target + "' is neither 'none' (in place) nor a kind of the task's entities");
      plan.next_targets.push_back(next);
    }
  }
  for (const YAML::Node& e : r.sequence(pn, "attention_edges")) {
    if (!e.IsSequence() || e.size() != 2) r.fail(e, "an attention edge is [SOURCE, TARGET]");
    plan.attention_edges.push_back({r.entity(e[0], spec), r.entity(e[1], spec)});
  }
  if (const std::string why = plan.inconsistency(info.options); !why.empty())
    r.fail(pn, "plan: " + why + " (no training makes this plan; retrain)");
  return plan;
}

}  // namespace

std::map<std::string, FileDigest> manifestFiles(const std::string& text, const std::string& path) {
  try {
    Reader r(path);
    return parseFiles(r, checkedRoot(r, text, path));
  } catch (const YAML::Exception& e) {
    throw yamlError(path, e);
  }
}

ModelInfo parseManifest(const std::string& text, const std::string& path, const task::TaskSpec& spec) {
  try {
    Reader r(path);
    const YAML::Node root = checkedRoot(r, text, path);
    ModelInfo info;
    info.format = r.text(root, "format");
    try {
      info.variant = variantFromString(r.text(root, "variant"));
    } catch (const Error& e) {
      r.fail(root["variant"], e.what());
    }
    info.options.variant = info.variant;
    info.options.seed = r.count(root, "seed");
    info.stop_reason = r.text(root, "stop_reason");
    info.files = parseFiles(r, root);
    info.fingerprint = task::parseFingerprint(r.need(root, "task_fingerprint"), path);
    for (const std::string& d : task::fingerprintDifferences(info.fingerprint, task::fingerprintOf(spec)))
      r.fail(root["task_fingerprint"], "task_fingerprint does not describe the model's task.yaml: " + d);

    if (r.texts(root, "entities") != spec.entityNames())
      r.fail(root["entities"], "entities do not match the model's task.yaml");
    parseVocabulary(r, root, info);
    parseHyperParameters(r, root, info.options);
    parseNormalisation(r, root, info);
    info.refined = parseRefinement(r, root, spec);
    info.plan = parsePlan(r, root, spec, info);
    // A model trained before dependencies were learned runs step by step (learned false).
    if (const YAML::Node deps = root["dependencies"]) info.dependencies = graph::parseDependencies(deps, path, spec);
    // What the model can transfer follows from the variant and the plan; the manifest says
    // it for a reader (a manifest written before it was recorded reads without it).
    if (const YAML::Node tn = root["transfer"]; tn) {
      const std::string derived = transferOf(info, spec).text();
      if (r.textAt(tn, "'transfer'") != derived)
        r.fail(tn, "transfer does not follow from the variant and the plan, which say: " + derived);
    }
    return info;
  } catch (const YAML::Exception& e) {
    throw yamlError(path, e);
  }
}

std::string lossCsvText(const std::vector<EpochRecord>& history) {
  std::ostringstream out;
  out << "epoch,loss,step_accuracy,seconds\n" << std::setprecision(17);
  for (const auto& r : history) out << r.epoch << ',' << r.loss << ',' << r.step_accuracy << ',' << r.seconds << '\n';
  return out.str();
}

std::vector<EpochRecord> readLossCsv(const std::string& path) {
  return parseLossCsv(readFile(path), path);
}

std::vector<EpochRecord> parseLossCsv(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != "epoch,loss,step_accuracy,seconds")
    throw Error(Diagnostic{path, 1, 1, "expected the header 'epoch,loss,step_accuracy,seconds'"});
  std::vector<EpochRecord> out;
  int number = 1;
  while (std::getline(in, line)) {
    ++number;
    EpochRecord r;
    char tail = 0;
    if (std::sscanf(line.c_str(), "%d,%lf,%lf,%lf%c", &r.epoch, &r.loss, &r.step_accuracy, &r.seconds, &tail) != 4 ||
        r.epoch != static_cast<int>(out.size()) + 1 || !std::isfinite(r.loss))
      throw Error(Diagnostic{
          path, number, 1, "expected 'epoch,loss,step_accuracy,seconds' for epoch " + std::to_string(out.size() + 1)});
    out.push_back(r);
  }
  return out;
}

}  // namespace files
}  // namespace ddace::tgn
