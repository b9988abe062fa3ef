#include "loss.h"

namespace ddace::tgn {

using torch::Tensor;

namespace {

Tensor nll(const Tensor& logits, const Tensor& target) {
  return -torch::log_softmax(logits, -1).gather(-1, target.unsqueeze(-1)).squeeze(-1);
}

}  // namespace

Tensor lossOf(const Heads& h, const Batch& batch, bool gnn, bool acting_targets) {
  const Tensor valid = batch.valid;
  const Tensor count = valid.sum();
  const int64_t n = batch.action.size(2);
  // Training token by token: an entity whose token of the step is given takes no loss.
  const Tensor vn = batch.given.defined() ? valid.unsqueeze(-1) * (1 - batch.given) : valid.unsqueeze(-1);
  Tensor target_loss;
  if (batch.given.defined()) {
    // Token by token: the step's next token is whichever of its remaining tokens the
    // decoder is surest of, among the pairs of every entity that may still act (acting or
    // not: who acts is chosen token by token too), so the loss asks only that the remaining
    // true tokens together be likely among those pairs: -log of their summed probability
    // under one softmax over the pairs' logits. An entity whose target depends on the
    // others' (its nearest goal is another's; the nearest free robot) need not be sure of
    // it before they are chosen. With one entity left that may act, it is its own loss.
    // A carrier's pairs are its loads' too (one decision), and a load's are none of its own.
    const Tensor acts = batch.action.gt(0).to(torch::kFloat);  // [B, T, N]
    Tensor logits = h.target, acting = acts;
    if (batch.carried.defined()) {
      logits = logits + torch::matmul(batch.carried, h.target);
      acting = acting * (1 - batch.carried.amax(-2));  // 0 for a load at some carrier
    }
    const Tensor open = vn * acting;
    Tensor pointable = open.unsqueeze(-1).expand_as(logits);
    if (batch.may_point.defined()) pointable = pointable + (vn * (1 - acts)).unsqueeze(-1) * batch.may_point;
    const Tensor pairs = (logits + (1 - pointable) * -1e9).flatten(-2);  // [B, T, N * (1 + N)]
    const Tensor truth = logits.gather(-1, batch.target.unsqueeze(-1)).squeeze(-1) + (1 - open) * -1e9;  // [B, T, N]
    const Tensor steps = open.sum(-1).gt(0).to(torch::kFloat);
    target_loss =
        ((torch::logsumexp(pairs, -1) - torch::logsumexp(truth, -1)) * steps).sum() / steps.sum().clamp_min(1);
  } else if (acting_targets) {
    const Tensor acting = vn * batch.action.gt(0).to(torch::kFloat);
    target_loss = (nll(h.target, batch.target) * acting).sum() / acting.sum().clamp_min(1);
  } else {
    target_loss = (nll(h.target, batch.target) * vn).sum() / (count * n);
  }
  Tensor loss = (nll(h.action, batch.action) * vn).sum() / (count * n) + target_loss +
                (nll(h.end, batch.end) * valid).sum() / count;
  if (gnn) loss = loss + ((h.delta - batch.delta).pow(2) * vn.unsqueeze(-1)).sum() / (count * n * 2);
  return loss;
}

Tensor correctOf(const Heads& h, const Batch& batch, bool gnn) {
  const Tensor act = h.action.argmax(-1), tgt = h.target.argmax(-1), end = h.end.argmax(-1);
  const Tensor entity_ok = act.eq(batch.action).logical_and(batch.action.eq(0).logical_or(tgt.eq(batch.target)));
  const Tensor labels_ok = entity_ok.all(-1);
  if (gnn) return labels_ok;
  return end.eq(batch.end).logical_and(batch.end.eq(1).logical_or(labels_ok));
}

}  // namespace ddace::tgn
