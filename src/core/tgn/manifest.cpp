#include "manifest.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/sha256.h"

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

const char* toString(AttentionKind k) {
  return k == AttentionKind::GatV2 ? "gatv2" : "gat";
}

AttentionKind attentionFromString(const std::string& name) {
  if (name == "gatv2") return AttentionKind::GatV2;
  if (name == "gat") return AttentionKind::GatConv;
  throw Error("attention '" + name + "' is not one of gatv2, gat");
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

namespace {

Error errorAt(const std::string& path, const YAML::Node& node, const std::string& message) {
  const auto mark = node.Mark();
  return Error(Diagnostic{path, mark.line >= 0 ? mark.line + 1 : 0, mark.column >= 0 ? mark.column + 1 : 0, message});
}

YAML::Node need(const std::string& path, const YAML::Node& parent, const std::string& key) {
  const YAML::Node n = parent[key];
  if (!n) throw errorAt(path, parent, "missing key '" + key + "'");
  return n;
}

template <typename T>
T as(const std::string& path, const YAML::Node& parent, const std::string& key) {
  const YAML::Node n = need(path, parent, key);
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    throw errorAt(path, n, "key '" + key + "' has a value of the wrong type");
  }
}

int entityIndex(const std::string& path, const YAML::Node& n, const task::TaskSpec& spec) {
  const std::string name = n.as<std::string>();
  const int i = spec.entityIndex(name);
  if (i < 0) throw errorAt(path, n, "unknown entity '" + name + "' (not in task.yaml)");
  return i;
}

graph::Decision decisionFromString(const std::string& path, const YAML::Node& n) {
  const std::string s = n.as<std::string>();
  for (auto d : {graph::Decision::KeptRecurrent, graph::Decision::KeptSameCluster, graph::Decision::DroppedRare,
                 graph::Decision::DroppedCrossCluster})
    if (s == graph::toString(d)) return d;
  throw errorAt(path, n, "unknown edge decision '" + s + "'");
}

}  // namespace

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

std::string manifestText(const ModelInfo& info, const task::TaskSpec& spec,
                         const std::map<std::string, FileDigest>& files) {
  const auto name = [&](int i) { return spec.entities.at(static_cast<size_t>(i)).name; };
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
  y << YAML::Key << "step_rules" << YAML::Value << YAML::Flow << YAML::BeginMap;
  y << YAML::Key << "exclusive_targets" << YAML::Value << info.step_rules.exclusive_targets;
  y << YAML::Key << "step_size" << YAML::Value << info.step_rules.step_size;
  y << YAML::EndMap;
  y << YAML::Key << "entities" << YAML::Value << YAML::Flow << spec.entityNames();
  y << YAML::Key << "vocabulary" << YAML::Value << YAML::Flow << info.vocabulary;
  y << YAML::Key << "hyper_parameters" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "max_epochs" << YAML::Value << o.max_epochs;
  y << YAML::Key << "heads" << YAML::Value << o.heads;
  y << YAML::Key << "head_channels" << YAML::Value << o.head_channels;
  y << YAML::Key << "gat_layers" << YAML::Value << o.gat_layers;
  y << YAML::Key << "gru_layers" << YAML::Value << o.gru_layers;
  y << YAML::Key << "gru_hidden" << YAML::Value << o.gru_hidden;
  y << YAML::Key << "identity_embedding" << YAML::Value << o.identity_embedding;
  y << YAML::Key << "identity_dim" << YAML::Value << o.identity_dim;
  y << YAML::Key << "attention" << YAML::Value << toString(o.attention);
  y << YAML::Key << "head_hidden" << YAML::Value << o.head_hidden;
  y << YAML::Key << "node_positions" << YAML::Value << o.node_positions;
  y << YAML::Key << "edge_displacement" << YAML::Value << o.edge_displacement;
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
  y << YAML::Key << "normalisation" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "mean_m" << YAML::Value << YAML::Flow << std::vector<double>{info.mean[0], info.mean[1]};
  y << YAML::Key << "std_m" << YAML::Value << YAML::Flow << std::vector<double>{info.std[0], info.std[1]};
  y << YAML::Key << "delta_std_m" << YAML::Value << YAML::Flow
    << std::vector<double>{info.delta_std[0], info.delta_std[1]};
  y << YAML::Key << "frame_dt_s" << YAML::Value << info.frame_dt_s;
  y << YAML::EndMap;
  const graph::RefinedGraph& g = info.refined;
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
  y << YAML::Key << "attention_edges" << YAML::Value << YAML::BeginSeq;
  for (const auto& e : info.attention_edges)
    y << YAML::Flow << std::vector<std::string>{name(e.source), name(e.target)};
  y << YAML::EndSeq;
  y << YAML::EndMap;
  const std::string body =
      std::string("# ddace model manifest (") + kModelFormat +
      "): written by `ddace train`, read by `ddace inspect` and the sequence node.\n"
      "# E' is refinement.edges with a 'kept' decision; attention_edges is what the network\n"
      "# attends over (paper: E'; scene: E' lifted to entity kinds; full-graph, gnn: every pair),\n"
      "# made symmetric. files: size and SHA-256 of each file; the last line is the SHA-256 of\n"
      "# everything before it. Do not edit: any change is refused.\n" +
      y.c_str() + "\n";
  return body + kManifestDigestKey + ": " + sha256Hex(body) + "\n";
}

namespace {

/// The manifest's YAML after the format check and the check of its own digest.
YAML::Node checkedRoot(const std::string& text, const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw Error(Diagnostic{path, e.mark.line + 1, e.mark.column + 1, "not valid YAML: " + e.msg});
  }
  if (!root.IsMap()) throw Error(Diagnostic{path, 1, 1, "not a model manifest (expected a YAML map)"});
  const std::string format = as<std::string>(path, root, "format");
  // "ddace-model/N": an older N is refused with what it lacks, a newer one as such.
  const std::string prefix = "ddace-model/";
  const std::string own = std::string(kModelFormat).substr(prefix.size());
  if (format.rfind(prefix, 0) == 0 && format != kModelFormat) {
    const std::string version = format.substr(prefix.size());
    const bool numeric = !version.empty() && version.size() <= 6 &&
                         std::all_of(version.begin(), version.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (numeric && std::stoi(version) < std::stoi(own))
      throw errorAt(
          path, root["format"],
          "format '" + format + "' is an older model format than " + kModelFormat +
              " (it lacks the step rules learned from the demonstrations" +
              (std::stoi(version) < 3 ? ", and its files are not bound by digests to the model and its task" : "") +
              "): retrain the model (ddace train)");
    if (numeric)
      throw errorAt(path, root["format"],
                    "format '" + format + "' is newer than " + kModelFormat + ", the newest this ddace reads");
  }
  if (format != kModelFormat) throw errorAt(path, root["format"], "format '" + format + "' is not " + kModelFormat);
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

std::map<std::string, FileDigest> parseFiles(const std::string& path, const YAML::Node& root) {
  const YAML::Node files = need(path, root, "files");
  if (!files.IsMap()) throw errorAt(path, files, "'files' must map file names to {bytes, sha256}");
  std::map<std::string, FileDigest> out;
  for (auto it = files.begin(); it != files.end(); ++it) {
    const std::string name = it->first.as<std::string>();
    if (name != kTask && name != kWeights && name != kLoss && name != "primitives.yaml")
      throw errorAt(path, it->first, "'files' names '" + name + "', not a file of a model directory");
    FileDigest d;
    d.bytes = as<uint64_t>(path, it->second, "bytes");
    d.sha256 = as<std::string>(path, it->second, "sha256");
    if (!isSha256Hex(d.sha256)) throw errorAt(path, it->second["sha256"], name + ": sha256 is not 64 hex digits");
    out[name] = d;
  }
  for (const char* required : {kTask, kWeights, kLoss})
    if (!out.count(required)) throw errorAt(path, files, std::string("'files' has no digest of ") + required);
  return out;
}

}  // namespace

std::map<std::string, FileDigest> manifestFiles(const std::string& text, const std::string& path) {
  try {
    return parseFiles(path, checkedRoot(text, path));
  } catch (const YAML::Exception& e) {
    throw Error(Diagnostic{path, e.mark.line + 1, e.mark.column + 1, e.msg});
  }
}

ModelInfo parseManifest(const std::string& text, const std::string& path, const task::TaskSpec& spec) {
  try {
    const YAML::Node root = checkedRoot(text, path);
    ModelInfo info;
    try {
      info.variant = variantFromString(as<std::string>(path, root, "variant"));
    } catch (const Error& e) {
      throw errorAt(path, root["variant"], e.what());
    }
    info.options.variant = info.variant;
    info.options.seed = as<uint64_t>(path, root, "seed");
    info.stop_reason = as<std::string>(path, root, "stop_reason");
    {
      const YAML::Node rules = need(path, root, "step_rules");
      info.step_rules.exclusive_targets = as<bool>(path, rules, "exclusive_targets");
      info.step_rules.step_size = as<int>(path, rules, "step_size");
      const int n = static_cast<int>(spec.entities.size());
      if (info.step_rules.step_size < 0 || info.step_rules.step_size > n)
        throw errorAt(path, rules["step_size"], "step_size must be in 0.." + std::to_string(n) + " (the entities)");
      if (info.variant != Variant::Scene && info.step_rules.any())
        throw errorAt(path, rules,
                      "step_rules are learned for the scene variant only (the others decode each entity on its own)");
    }
    info.files = parseFiles(path, root);
    info.fingerprint = task::parseFingerprint(need(path, root, "task_fingerprint"), path);
    for (const std::string& d : task::fingerprintDifferences(info.fingerprint, task::fingerprintOf(spec)))
      throw errorAt(path, root["task_fingerprint"], "task_fingerprint does not describe the model's task.yaml: " + d);

    const YAML::Node ents = need(path, root, "entities");
    if (ents.as<std::vector<std::string>>() != spec.entityNames())
      throw errorAt(path, ents, "entities do not match the model's task.yaml");
    info.vocabulary = as<std::vector<std::string>>(path, root, "vocabulary");
    {
      // The vocabulary's order is the action head's class order: it must be the training
      // directory's, whose sorted set the fingerprint records.
      std::vector<std::string> sorted = info.vocabulary;
      std::sort(sorted.begin(), sorted.end());
      if (info.vocabulary.empty() || sorted != info.fingerprint.vocabulary ||
          std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
        throw errorAt(path, root["vocabulary"], "vocabulary does not match task_fingerprint.vocabulary");
    }

    const YAML::Node hp = need(path, root, "hyper_parameters");
    TrainOptions& o = info.options;
    o.max_epochs = as<int>(path, hp, "max_epochs");
    o.heads = as<int>(path, hp, "heads");
    o.head_channels = as<int>(path, hp, "head_channels");
    o.gat_layers = as<int>(path, hp, "gat_layers");
    o.gru_layers = as<int>(path, hp, "gru_layers");
    o.gru_hidden = as<int>(path, hp, "gru_hidden");
    o.identity_embedding = as<bool>(path, hp, "identity_embedding");
    o.identity_dim = as<int>(path, hp, "identity_dim");
    try {
      o.attention = attentionFromString(as<std::string>(path, hp, "attention"));
    } catch (const Error& e) {
      throw errorAt(path, hp["attention"], e.what());
    }
    o.head_hidden = as<int>(path, hp, "head_hidden");
    o.node_positions = as<bool>(path, hp, "node_positions");
    o.edge_displacement = as<bool>(path, hp, "edge_displacement");
    o.weight_decay = as<double>(path, hp, "weight_decay");
    o.dropout = as<double>(path, hp, "dropout");
    o.learning_rate = as<double>(path, hp, "learning_rate");
    o.batch_demos = as<int>(path, hp, "batch_demos");
    o.plateau_patience = as<int>(path, hp, "plateau_patience");
    o.plateau_delta = as<double>(path, hp, "plateau_delta");
    o.threads = as<int>(path, hp, "threads");
    o.refinement.keep_support = as<double>(path, hp, "keep_support");
    o.refinement.drop_support = as<double>(path, hp, "drop_support");
    o.refinement.seed = o.seed;
    try {
      o.validate();
    } catch (const Error& e) {
      throw errorAt(path, hp, e.what());
    }

    const YAML::Node norm = need(path, root, "normalisation");
    const auto pair = [&](const std::string& key, double* out, bool positive) {
      const auto v = as<std::vector<double>>(path, norm, key);
      if (v.size() != 2 || !std::isfinite(v[0]) || !std::isfinite(v[1]) || (positive && (v[0] <= 0 || v[1] <= 0)))
        throw errorAt(path, norm[key], key + " must be two finite numbers" + (positive ? " > 0" : ""));
      out[0] = v[0];
      out[1] = v[1];
    };
    pair("mean_m", info.mean, false);
    pair("std_m", info.std, true);
    pair("delta_std_m", info.delta_std, true);
    info.frame_dt_s = as<double>(path, norm, "frame_dt_s");
    if (!(info.frame_dt_s > 0 && info.frame_dt_s <= 10))
      throw errorAt(path, norm["frame_dt_s"], "frame_dt_s must be in (0, 10] seconds");

    const YAML::Node ref = need(path, root, "refinement");
    graph::RefinedGraph& g = info.refined;
    g.nodes = static_cast<int>(spec.entities.size());
    g.demonstrations = as<int>(path, ref, "demonstrations");
    if (g.demonstrations < 1 || g.demonstrations > task::kMaxFingerprintCount)
      throw errorAt(path, ref["demonstrations"],
                    "demonstrations must be in 1.." + std::to_string(task::kMaxFingerprintCount));
    g.clusters = as<int>(path, ref, "clusters");
    if (g.clusters < 1 || g.clusters > g.nodes)
      throw errorAt(path, ref["clusters"], "clusters must be in 1.." + std::to_string(g.nodes) + " (the entities)");
    g.cluster.assign(static_cast<size_t>(g.nodes), 0);
    const YAML::Node cof = need(path, ref, "cluster_of");
    for (auto it = cof.begin(); it != cof.end(); ++it) {
      const int c = it->second.as<int>();
      if (c < 0 || c >= g.clusters) throw errorAt(path, it->second, "cluster index out of 0..clusters-1");
      g.cluster[static_cast<size_t>(entityIndex(path, it->first, spec))] = c;
    }
    const auto eig = as<std::vector<double>>(path, ref, "eigenvalues");
    if (eig.size() > static_cast<size_t>(g.nodes))
      throw errorAt(path, ref["eigenvalues"], "more eigenvalues than entities");
    g.eigenvalues = Eigen::Map<const Eigen::VectorXd>(eig.data(), static_cast<Eigen::Index>(eig.size()));
    for (const YAML::Node& e : need(path, ref, "edges")) {
      graph::EdgeStats s;
      s.edge = {entityIndex(path, need(path, e, "source"), spec), entityIndex(path, need(path, e, "target"), spec)};
      s.frequency = as<int>(path, e, "frequency");
      s.demos = as<int>(path, e, "demos");
      s.support = as<double>(path, e, "support");
      if (s.frequency < 0 || s.demos < 0 || s.demos > g.demonstrations || !(s.support >= 0 && s.support <= 1))
        throw errorAt(path, e, "an edge needs frequency >= 0, demos in 0..demonstrations, support in [0, 1]");
      s.decision = decisionFromString(path, need(path, e, "decision"));
      g.edges.push_back(s);
      if (graph::isKept(s.decision)) g.kept.push_back(s.edge);
    }
    for (const YAML::Node& e : need(path, root, "attention_edges")) {
      if (!e.IsSequence() || e.size() != 2) throw errorAt(path, e, "an attention edge is [SOURCE, TARGET]");
      info.attention_edges.push_back({entityIndex(path, e[0], spec), entityIndex(path, e[1], spec)});
    }
    return info;
  } catch (const YAML::Exception& e) {
    throw Error(Diagnostic{path, e.mark.line + 1, e.mark.column + 1, e.msg});
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
