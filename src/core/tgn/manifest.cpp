#include "manifest.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

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

std::string hex(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

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

uint64_t fileHash(const std::string& path) {
  const std::string bytes = readFile(path);
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(Diagnostic{path, 0, 0, "cannot read the file (missing?)"});
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void writeFile(const std::string& path, const std::string& text) {
  writeTextFile(path, text);
}

std::string manifestText(const ModelInfo& info, const task::TaskSpec& spec, uint64_t weights_hash,
                         uint64_t weights_bytes) {
  const auto name = [&](int i) { return spec.entities.at(static_cast<size_t>(i)).name; };
  const TrainOptions& o = info.options;
  YAML::Emitter y;
  y.SetDoublePrecision(17);
  y << YAML::BeginMap;
  y << YAML::Key << "format" << YAML::Value << kModelFormat;
  y << YAML::Key << "variant" << YAML::Value << toString(info.variant);
  y << YAML::Key << "seed" << YAML::Value << o.seed;
  y << YAML::Key << "task" << YAML::Value << kTask;
  y << YAML::Key << "weights" << YAML::Value << kWeights;
  y << YAML::Key << "weights_bytes" << YAML::Value << weights_bytes;
  y << YAML::Key << "weights_fnv1a64" << YAML::Value << hex(weights_hash);
  y << YAML::Key << "loss" << YAML::Value << kLoss;
  y << YAML::Key << "epochs" << YAML::Value << info.history.size();
  y << YAML::Key << "stop_reason" << YAML::Value << info.stop_reason;
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
  return std::string("# ddace model manifest (") + kModelFormat +
         "): written by `ddace train`, read by `ddace inspect` and the sequence node.\n"
         "# E' is refinement.edges with a 'kept' decision; attention_edges is what the network\n"
         "# attends over (paper: E'; scene: E' lifted to entity kinds; full-graph, gnn: every pair),\n"
         "# made symmetric.\n" +
         y.c_str() + "\n";
}

ModelInfo parseManifest(const std::string& path, const task::TaskSpec& spec, uint64_t* weights_hash,
                        uint64_t* weights_bytes) {
  const std::string text = readFile(path);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw Error(Diagnostic{path, e.mark.line + 1, e.mark.column + 1, "not valid YAML: " + e.msg});
  }
  if (!root.IsMap()) throw Error(Diagnostic{path, 1, 1, "not a model manifest (expected a YAML map)"});
  try {
    const std::string format = as<std::string>(path, root, "format");
    if (format != kModelFormat) throw errorAt(path, root["format"], "format '" + format + "' is not " + kModelFormat);
    ModelInfo info;
    try {
      info.variant = variantFromString(as<std::string>(path, root, "variant"));
    } catch (const Error& e) {
      throw errorAt(path, root["variant"], e.what());
    }
    info.options.variant = info.variant;
    info.options.seed = as<uint64_t>(path, root, "seed");
    info.stop_reason = as<std::string>(path, root, "stop_reason");
    const std::string hash = as<std::string>(path, root, "weights_fnv1a64");
    char* end = nullptr;
    *weights_hash = std::strtoull(hash.c_str(), &end, 16);
    if (hash.size() != 16 || *end != '\0') throw errorAt(path, root["weights_fnv1a64"], "not a 64-bit hex hash");
    *weights_bytes = as<uint64_t>(path, root, "weights_bytes");

    const YAML::Node ents = need(path, root, "entities");
    if (ents.as<std::vector<std::string>>() != spec.entityNames())
      throw errorAt(path, ents, "entities do not match the model's task.yaml");
    info.vocabulary = as<std::vector<std::string>>(path, root, "vocabulary");

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
    if (!(info.frame_dt_s > 0)) throw errorAt(path, norm["frame_dt_s"], "frame_dt_s must be positive");

    const YAML::Node ref = need(path, root, "refinement");
    graph::RefinedGraph& g = info.refined;
    g.nodes = static_cast<int>(spec.entities.size());
    g.demonstrations = as<int>(path, ref, "demonstrations");
    g.clusters = as<int>(path, ref, "clusters");
    g.cluster.assign(static_cast<size_t>(g.nodes), 0);
    const YAML::Node cof = need(path, ref, "cluster_of");
    for (auto it = cof.begin(); it != cof.end(); ++it)
      g.cluster[static_cast<size_t>(entityIndex(path, it->first, spec))] = it->second.as<int>();
    const auto eig = as<std::vector<double>>(path, ref, "eigenvalues");
    g.eigenvalues = Eigen::Map<const Eigen::VectorXd>(eig.data(), static_cast<Eigen::Index>(eig.size()));
    for (const YAML::Node& e : need(path, ref, "edges")) {
      graph::EdgeStats s;
      s.edge = {entityIndex(path, need(path, e, "source"), spec), entityIndex(path, need(path, e, "target"), spec)};
      s.frequency = as<int>(path, e, "frequency");
      s.demos = as<int>(path, e, "demos");
      s.support = as<double>(path, e, "support");
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
  std::istringstream in(readFile(path));
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
