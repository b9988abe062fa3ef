#include "ddace/exec/outbox.h"

#include <algorithm>
#include <cmath>

#include "ddace/common/error.h"

namespace ddace::exec {

Outbox::Outbox(double resend_after_s) : resend_after_s_(resend_after_s) {
  if (!(resend_after_s > 0) || !std::isfinite(resend_after_s)) throw Error("outbox: resend_after_s must be positive");
}

void Outbox::sent(Kind kind, uint32_t id, double now_s) {
  pending_[{kind, id}] = now_s;
}

void Outbox::acknowledged(Kind kind, uint32_t id) {
  pending_.erase({kind, id});
}

void Outbox::forget(Kind kind) {
  for (auto it = pending_.begin(); it != pending_.end();) it = it->first.first == kind ? pending_.erase(it) : ++it;
}

std::vector<std::pair<Outbox::Kind, uint32_t>> Outbox::due(double now_s) {
  std::vector<std::pair<double, std::pair<Kind, uint32_t>>> due;
  for (auto& [key, sent_s] : pending_)
    if (now_s - sent_s >= resend_after_s_) due.push_back({sent_s, key});
  std::stable_sort(due.begin(), due.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::pair<Kind, uint32_t>> out;
  for (const auto& [sent_s, key] : due) {
    pending_[key] = now_s;
    out.push_back(key);
  }
  return out;
}

}  // namespace ddace::exec
