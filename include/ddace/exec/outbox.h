// At-least-once delivery of the coordinator's requests and segments: what was sent and
// not yet acknowledged goes out again, unchanged (same id), every `resend_after_s`.
// A receiver that subscribed just too late misses the first copy; receivers ignore an id
// they already handle, so a copy never makes a second decision or a second segment.
//
// Owns: which ids await an answer and when each is due again. Must not: hold or send the
// messages (the node keeps them by id), read clocks (`now_s` comes in). Units: seconds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace ddace::exec {

class Outbox {
 public:
  enum class Kind : uint8_t { Decision = 0, Path = 1, Segment = 2 };

  /// Throws ddace::Error unless resend_after_s is positive and finite.
  explicit Outbox(double resend_after_s);

  /// `id` of `kind` went out at `now_s` and awaits an answer.
  void sent(Kind kind, uint32_t id, double now_s);
  /// An answer for `id` arrived (any answer: a status, a path, a decision). Unknown ids are ignored.
  void acknowledged(Kind kind, uint32_t id);
  /// Nothing of `kind` needs an answer any more (the run left the phase that asked).
  void forget(Kind kind);
  void clear() { pending_.clear(); }

  /// The ids due again at `now_s` (unanswered for resend_after_s since they were last
  /// sent), oldest first; their clocks restart at `now_s`.
  std::vector<std::pair<Kind, uint32_t>> due(double now_s);
  bool pending(Kind kind, uint32_t id) const { return pending_.count({kind, id}) != 0; }
  size_t size() const { return pending_.size(); }
  double resendAfter() const { return resend_after_s_; }

 private:
  double resend_after_s_;
  std::map<std::pair<Kind, uint32_t>, double> pending_;  ///< -> last sent, seconds
};

}  // namespace ddace::exec
