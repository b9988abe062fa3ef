// The GAT layer equals PyTorch Geometric GATConv semantics on a tiny graph with fixed
// weights (reference values: scripts/make_gat_fixture.py, stored in test/data/tgn).
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>

#include "ddace/common/repository.h"
#include "ddace/common/error.h"
#include "ddace/tgn/detail.h"
#include "ddace/tgn/sequence_model.h"

using namespace ddace;

namespace {

std::map<std::string, std::vector<double>> readFixture(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::map<std::string, std::vector<double>> out;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::string key;
    ss >> key;
    double v;
    while (ss >> v) out[key].push_back(v);
  }
  return out;
}

std::vector<float> floats(const std::vector<double>& v) {
  return std::vector<float>(v.begin(), v.end());
}

}  // namespace

TEST(Gat, EqualsTheGatConvReferenceOnATinyGraph) {
  auto f = readFixture(
      (ddace::findRepository("", {"test/data/tgn/gat_fixture.txt"}) / "test/data/tgn/gat_fixture.txt").string());
  ASSERT_EQ(f["nodes"].size(), 1u);
  const int nodes = static_cast<int>(f["nodes"][0]);
  tgn::detail::GatWeights w;
  w.in = static_cast<int>(f["in"][0]);
  w.heads = static_cast<int>(f["heads"][0]);
  w.channels = static_cast<int>(f["channels"][0]);
  w.weight = floats(f["weight"]);
  w.att_src = floats(f["att_src"]);
  w.att_dst = floats(f["att_dst"]);
  w.bias = floats(f["bias"]);
  std::vector<graph::Edge> edges;
  for (size_t i = 0; i + 1 < f["edges"].size(); i += 2)
    edges.push_back({static_cast<int>(f["edges"][i]), static_cast<int>(f["edges"][i + 1])});
  ASSERT_EQ(edges.size(), 6u);
  const std::vector<float> y = tgn::detail::gatForward(w, floats(f["x"]), nodes, edges);
  const std::vector<double>& ref = f["out"];
  ASSERT_EQ(y.size(), ref.size());
  for (size_t i = 0; i < y.size(); ++i) EXPECT_NEAR(y[i], ref[i], 1e-5) << "output " << i;

  // Direction matters: reversed edges give a different result (messages flow source -> target).
  std::vector<graph::Edge> reversed;
  for (const auto& e : edges) reversed.push_back({e.target, e.source});
  const std::vector<float> r = tgn::detail::gatForward(w, floats(f["x"]), nodes, reversed);
  double diff = 0;
  for (size_t i = 0; i < r.size(); ++i) diff += std::abs(r[i] - y[i]);
  EXPECT_GT(diff, 1e-2);
}

TEST(Gat, RejectsMismatchedArrays) {
  tgn::detail::GatWeights w;
  w.in = 2;
  w.heads = 1;
  w.channels = 2;
  w.weight.assign(4, 0.f);
  w.att_src.assign(2, 0.f);
  w.att_dst.assign(2, 0.f);
  w.bias.assign(2, 0.f);
  EXPECT_THROW(tgn::detail::gatForward(w, std::vector<float>(5, 0.f), 3, {}), Error);
  EXPECT_THROW(tgn::detail::gatForward(w, std::vector<float>(6, 0.f), 3, {{0, 3}}), Error);
  EXPECT_NO_THROW(tgn::detail::gatForward(w, std::vector<float>(6, 0.f), 3, {{0, 2}}));
}
