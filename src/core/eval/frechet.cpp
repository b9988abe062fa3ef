#include "ddace/eval/frechet.h"

#include <algorithm>

#include "ddace/common/error.h"
#include "ddace/gp/canonical.h"

namespace ddace::eval {

double frechetDistance(const std::vector<Eigen::Vector2d>& p, const std::vector<Eigen::Vector2d>& q) {
  if (p.empty() || q.empty()) throw Error("Fréchet distance of an empty path");
  // The coupling distance is symmetric: iterate over the longer path, keep one row
  // of the shorter one.
  const auto& outer = p.size() >= q.size() ? p : q;
  const auto& inner = p.size() >= q.size() ? q : p;
  std::vector<double> row(inner.size());
  for (size_t i = 0; i < outer.size(); ++i) {
    double diagonal = 0;  // row[j - 1] of the previous outer index
    for (size_t j = 0; j < inner.size(); ++j) {
      const double d = (outer[i] - inner[j]).norm();
      const double above = row[j];  // (i - 1, j)
      double best;
      if (i == 0 && j == 0) {
        best = d;
      } else if (i == 0) {
        best = std::max(row[j - 1], d);
      } else if (j == 0) {
        best = std::max(above, d);
      } else {
        best = std::max(std::min({above, diagonal, row[j - 1]}), d);
      }
      diagonal = above;
      row[j] = best;
    }
  }
  return row.back();
}

double normalisedFrechet(const std::vector<Eigen::Vector2d>& generated,
                         const std::vector<Eigen::Vector2d>& ground_truth) {
  if (generated.empty() || ground_truth.empty()) throw Error("Fréchet distance of an empty path");
  const gp::CanonicalFrame frame(ground_truth.front(), ground_truth.back());
  return frechetDistance(frame.toCanonical(gp::resampleByProgress(generated, kFrechetPoints)),
                         frame.toCanonical(gp::resampleByProgress(ground_truth, kFrechetPoints)));
}

}  // namespace ddace::eval
