// Test- and bench-only entry points (include/ddace/tgn/detail.h).
#include <torch/torch.h>

#include <iomanip>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"
#include "manifest.h"
#include "model_impl.h"

namespace ddace::tgn {

using torch::Tensor;

void writeTrainingTensors(const task::TaskDir& train, const TrainOptions& options, const std::string& path) {
  // The network SequenceModel::train runs on `train` (the "Fixed order" rule included).
  auto impl = prepare(train, options);
  impl->build();
  const std::vector<Sequence> seqs = impl->sequences(train.demos);
  std::ostringstream out;
  const NetConfig& c = impl->cfg;
  out << "# ddace tgn training tensors (keyframe variants); read by bench/tgn_train_reference.py\n";
  out << "variant " << toString(impl->info.variant) << "\n";
  // Without them (scene, "Fixed order") rel is all zero and the heads read each entity's input too.
  out << "relative_features " << (impl->info.plan.relative_features ? 1 : 0) << "\n";
  out << "nodes " << c.nodes << "\nactions " << c.actions << "\ntargets " << c.targets << "\nfeatures " << c.features
      << "\ndemos " << seqs.size() << "\nmask";
  const Tensor mask =
      (impl->isScene() ? impl->scene->mask.view({c.nodes, c.nodes}) : impl->net->att.mask).to(torch::kLong);
  for (int64_t i = 0; i < mask.numel(); ++i) out << ' ' << mask.view(-1)[i].item<int64_t>();
  out << '\n' << std::setprecision(9);
  for (const auto& s : seqs) {
    out << "sequence " << s.x.size(0) << "\nx";
    const Tensor x = s.x.contiguous().view(-1);
    for (int64_t i = 0; i < x.numel(); ++i) out << ' ' << x[i].item<float>();
    for (const auto& [name, t] :
         {std::pair<const char*, Tensor>{"action", s.action}, {"target", s.target}, {"end", s.end}}) {
      out << '\n' << name;
      const Tensor v = t.contiguous().view(-1);
      for (int64_t i = 0; i < v.numel(); ++i) out << ' ' << v[i].item<int64_t>();
    }
    if (s.rel.defined()) {
      out << "\nrel";
      const Tensor r = s.rel.contiguous().view(-1);
      for (int64_t i = 0; i < r.numel(); ++i) out << ' ' << r[i].item<float>();
    }
    out << '\n';
  }
  files::writeFile(path, out.str());
}

namespace detail {

std::vector<float> gatForward(const GatWeights& w, const std::vector<float>& x, int nodes,
                              const std::vector<graph::Edge>& edges) {
  const int width = w.heads * w.channels;
  if (x.size() != static_cast<size_t>(nodes * w.in) || w.weight.size() != static_cast<size_t>(width * w.in) ||
      w.att_src.size() != static_cast<size_t>(width) || w.att_dst.size() != static_cast<size_t>(width) ||
      w.bias.size() != static_cast<size_t>(width))
    throw Error("gatForward: array sizes do not match in/heads/channels/nodes");
  for (const auto& e : edges)
    if (e.source < 0 || e.source >= nodes || e.target < 0 || e.target >= nodes)
      throw Error("gatForward: an edge names a node outside 0.." + std::to_string(nodes - 1));
  torch::NoGradGuard no_grad;
  GatLayer layer(w.in, w.heads, w.channels);
  auto from = [](const std::vector<float>& v, std::vector<int64_t> shape) {
    return torch::from_blob(const_cast<float*>(v.data()), shape).clone();
  };
  layer->lin->weight.copy_(from(w.weight, {width, w.in}));
  layer->att_src.copy_(from(w.att_src, {w.heads, w.channels}));
  layer->att_dst.copy_(from(w.att_dst, {w.heads, w.channels}));
  layer->bias.copy_(from(w.bias, {width}));
  const Tensor y =
      layer->forward(from(x, {1, nodes, w.in}), Attention(maskFromEdges(nodes, edges, false))).contiguous();
  return std::vector<float>(y.data_ptr<float>(), y.data_ptr<float>() + y.numel());
}

}  // namespace detail
}  // namespace ddace::tgn
