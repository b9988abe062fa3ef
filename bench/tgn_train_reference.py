#!/usr/bin/python3
"""Python/PyTorch reference for bench_tgn_train and bench_tgn_decision: the same networks and
the same training loop (Adam with gradient-norm clipping at 1, mini-batches of whole
demonstrations in a shuffled order, masked cross-entropies, an eval-mode step accuracy after
every epoch) as src/core/tgn, on the tensors that ddace::tgn::writeTrainingTensors wrote
(their `variant` line picks the network):
  scene  (src/core/tgn/scene_network.cpp) GATv2 attention with relative edge features in the
         logits and the messages, ReLU, dropout, residuals, mean pooling, 2-layer GRU,
         per-entity action heads and a pointer over the candidate targets; with
         `relative_features 0` ("Fixed order", docs/tgn.md: the tensors' rel is all zero) the
         GRU and the heads read each entity's own input beside the last layer's output;
  paper  (src/core/tgn/network.cpp) 3 GAT layers with GATConv semantics, BatchNorm, ReLU,
         dropout, mean pooling, 2-layer GRU, linear heads with the self-target mask.
Prints one JSON object.

Usage:
  tgn_train_reference.py train TENSORS --epochs N [--batch 8] [--lr 0.005] ...
  tgn_train_reference.py decision TENSORS --history K --repeats R
"""
import argparse
import json
import random
import time

import torch
import torch.nn.functional as F


def read_tensors(path):
    meta, seqs = {}, []
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                continue
            key, _, rest = line.strip().partition(" ")
            if key == "sequence":
                seqs.append({"t": int(rest)})
            elif key in ("x", "action", "target", "end", "rel"):
                seqs[-1][key] = rest.split()
            elif key == "mask":
                meta["mask"] = [int(v) for v in rest.split()]
            elif key == "variant":
                meta["variant"] = rest
            else:
                meta[key] = int(rest)
    n, fe = meta["nodes"], meta["features"]
    out = []
    for s in seqs:
        t = s["t"]
        out.append({
            "x": torch.tensor([float(v) for v in s["x"]]).view(t, n, fe),
            "action": torch.tensor([int(v) for v in s["action"]]).view(t, n),
            "target": torch.tensor([int(v) for v in s["target"]]).view(t, n),
            "end": torch.tensor([int(v) for v in s["end"]]).view(t),
        })
        if "rel" in s:
            out[-1]["rel"] = torch.tensor([float(v) for v in s["rel"]]).view(t, n, n, -1)
    mask = torch.tensor(meta["mask"], dtype=torch.bool).view(n, n)
    return meta, mask, out


class Gat(torch.nn.Module):
    def __init__(self, fin, heads, channels):
        super().__init__()
        self.heads, self.channels = heads, channels
        self.lin = torch.nn.Linear(fin, heads * channels, bias=False)
        self.att_src = torch.nn.Parameter(torch.empty(heads, channels))
        self.att_dst = torch.nn.Parameter(torch.empty(heads, channels))
        self.bias = torch.nn.Parameter(torch.zeros(heads * channels))
        torch.nn.init.xavier_uniform_(self.lin.weight)
        torch.nn.init.xavier_uniform_(self.att_src)
        torch.nn.init.xavier_uniform_(self.att_dst)

    def forward(self, x, att):
        mask, src, dst = att
        s, n = x.shape[0], x.shape[1]
        h = self.lin(x).view(s, n, self.heads, self.channels)
        a_src = (h * self.att_src).sum(-1)
        a_dst = (h * self.att_dst).sum(-1)
        e = F.leaky_relu(a_dst.unsqueeze(2) + a_src.unsqueeze(1), 0.2)
        e = e.masked_fill(mask.logical_not().view(1, n, n, 1), float("-inf"))
        alpha = torch.softmax(e, 2)
        messages = alpha[:, dst, src].unsqueeze(-1) * h.index_select(1, src)
        out = torch.zeros(s, n, self.heads, self.channels).index_add(1, dst, messages)
        return out.reshape(s, n, self.heads * self.channels) + self.bias


class Network(torch.nn.Module):
    def __init__(self, meta, mask, a):
        super().__init__()
        self.n, self.actions, self.targets = meta["nodes"], meta["actions"], meta["targets"]
        dst, src = mask.nonzero(as_tuple=True)
        self.att = (mask, src.contiguous(), dst.contiguous())
        self.dropout, self.identity_dim = a.dropout, a.identity_dim
        self.identity = torch.nn.Embedding(self.n, a.identity_dim)
        width = a.heads * a.head_channels
        fin = meta["features"] + a.identity_dim
        self.gat = torch.nn.ModuleList([Gat(fin if l == 0 else width, a.heads, a.head_channels) for l in range(3)])
        self.bn = torch.nn.ModuleList([torch.nn.BatchNorm1d(width) for _ in range(3)])
        self.gru = torch.nn.GRU(width, a.gru_hidden, num_layers=2, batch_first=True)
        self.head = torch.nn.Linear(a.gru_hidden, self.n * (self.actions + self.targets) + 2)
        self.self_mask = torch.zeros(self.n, self.targets)
        for i in range(self.n):
            self.self_mask[i, i + 1] = -1e9

    def encode(self, x):
        s, n = x.shape[0], x.shape[1]
        x = torch.cat([x, self.identity.weight.unsqueeze(0).expand(s, n, self.identity_dim)], 2)
        for gat, bn in zip(self.gat, self.bn):
            x = gat(x, self.att)
            w = x.shape[2]
            x = bn(x.reshape(s * n, w)).view(s, n, w)
            x = F.dropout(F.relu(x), self.dropout, self.training)
        return x.mean(1)

    def heads(self, z):
        y = self.head(z)
        lead = list(z.shape[:-1])
        na, nt = self.n * self.actions, self.n * self.targets
        action = y.narrow(-1, 0, na).reshape(lead + [self.n, self.actions])
        target = y.narrow(-1, na, nt).reshape(lead + [self.n, self.targets]) + self.self_mask
        end = y.narrow(-1, na + nt, 2)
        return action, target, end


class SceneLayer(torch.nn.Module):
    def __init__(self, fin, rel, heads, channels):
        super().__init__()
        self.heads, self.channels = heads, channels
        width = heads * channels
        self.lin_src = torch.nn.Linear(fin, width, bias=False)
        self.lin_dst = torch.nn.Linear(fin, width, bias=False)
        self.lin_edge = torch.nn.Linear(rel, width, bias=False)
        self.att = torch.nn.Parameter(torch.empty(heads, channels))
        self.bias = torch.nn.Parameter(torch.zeros(width))
        for w in (self.lin_src.weight, self.lin_dst.weight, self.lin_edge.weight, self.att):
            torch.nn.init.xavier_uniform_(w)

    def forward(self, x, rel, mask):
        s, n = x.shape[0], x.shape[1]
        hs = self.lin_src(x).view(s, 1, n, self.heads, self.channels)
        hd = self.lin_dst(x).view(s, n, 1, self.heads, self.channels)
        msg = hs + self.lin_edge(rel).view(s, n, n, self.heads, self.channels)
        logit = (F.leaky_relu(hd + msg, 0.2) * self.att).sum(-1)
        alpha = torch.softmax(logit.masked_fill(mask.logical_not(), -1e30), 2)
        return (alpha.unsqueeze(-1) * msg).sum(2).reshape(s, n, self.heads * self.channels) + self.bias


class SceneNetwork(torch.nn.Module):
    def __init__(self, meta, mask, a, rel):
        super().__init__()
        self.n, self.actions = meta["nodes"], meta["actions"]
        self.mask = mask.view(1, self.n, self.n, 1)
        self.dropout, self.identity_dim = a.dropout, a.identity_dim
        self.identity = torch.nn.Embedding(self.n, a.identity_dim)
        attention_width, hidden = a.heads * a.head_channels, a.head_hidden
        fin = meta["features"] + a.identity_dim
        self.layers = torch.nn.ModuleList(
            [SceneLayer(fin if l == 0 else attention_width, rel, a.heads, a.head_channels) for l in range(3)])
        self.relative = meta.get("relative_features", 1) == 1
        width = attention_width + (0 if self.relative else fin)
        self.gru = torch.nn.GRU(width, a.gru_hidden, num_layers=2, batch_first=True)
        self.act_h = torch.nn.Linear(width, hidden)
        self.act_z = torch.nn.Linear(a.gru_hidden, hidden, bias=False)
        self.act_out = torch.nn.Linear(hidden, self.actions)
        self.none_out = torch.nn.Linear(hidden, 1)
        self.ptr_i = torch.nn.Linear(width, hidden)
        self.ptr_j = torch.nn.Linear(width, hidden, bias=False)
        self.ptr_r = torch.nn.Linear(rel, hidden, bias=False)
        self.ptr_z = torch.nn.Linear(a.gru_hidden, hidden, bias=False)
        self.ptr_out = torch.nn.Linear(hidden, 1)
        self.end = torch.nn.Linear(a.gru_hidden, 2)
        self.self_mask = torch.eye(self.n) * -1e9

    def encode(self, x, rel):
        s, n = x.shape[0], x.shape[1]
        x = torch.cat([x, self.identity.weight.unsqueeze(0).expand(s, n, self.identity_dim)], 2)
        inputs = x
        for l, layer in enumerate(self.layers):
            y = F.dropout(F.relu(layer(x, rel, self.mask)), self.dropout, self.training)
            x = y if l == 0 else x + y
        return x if self.relative else torch.cat([x, inputs], 2)

    def heads(self, nodes, rel, z):
        zu = z.unsqueeze(-2)
        hidden = F.relu(self.act_h(nodes) + self.act_z(zu))
        pre = (self.ptr_i(nodes).unsqueeze(-2) + self.ptr_j(nodes).unsqueeze(-3) + self.ptr_r(rel)
               + self.ptr_z(zu).unsqueeze(-2))
        scores = self.ptr_out(F.relu(pre)).squeeze(-1) + self.self_mask
        return self.act_out(hidden), torch.cat([self.none_out(hidden), scores], -1), self.end(z)


def collate(seqs, which):
    b = len(which)
    t = max(seqs[i]["x"].shape[0] for i in which)
    slots = []
    for k, i in enumerate(which):
        slots += [k * t + j for j in range(seqs[i]["x"].shape[0])]
    slot = torch.tensor(slots, dtype=torch.long)
    x = torch.cat([seqs[i]["x"] for i in which])
    n = x.shape[1]

    def scatter(values, shape):
        out = torch.zeros([b * t] + list(values.shape[1:]), dtype=values.dtype).index_copy(0, slot, values)
        return out.view(shape)

    extra = {}
    if "rel" in seqs[which[0]]:
        extra["rel"] = torch.cat([seqs[i]["rel"] for i in which])
        extra["rel_slots"] = scatter(extra["rel"], [b, t, n, n, extra["rel"].shape[-1]])
    return {
        **extra,
        "b": b, "t": t, "x": x, "slot": slot,
        "valid": scatter(torch.ones(x.shape[0]), [b, t]),
        "action": scatter(torch.cat([seqs[i]["action"] for i in which]), [b, t, n]),
        "target": scatter(torch.cat([seqs[i]["target"] for i in which]), [b, t, n]),
        "end": scatter(torch.cat([seqs[i]["end"] for i in which]), [b, t]),
    }


def run(net, batch):
    if isinstance(net, SceneNetwork):
        nodes = net.encode(batch["x"], batch["rel"])
        bt, n, w = batch["b"] * batch["t"], nodes.shape[1], nodes.shape[2]
        pooled = torch.zeros(bt, w).index_copy(0, batch["slot"], nodes.mean(1))
        z, _ = net.gru(pooled.view(batch["b"], batch["t"], w))
        slots = torch.zeros(bt, n, w).index_copy(0, batch["slot"], nodes).view(batch["b"], batch["t"], n, w)
        return net.heads(slots, batch["rel_slots"], z)
    emb = net.encode(batch["x"])
    seq = torch.zeros(batch["b"] * batch["t"], emb.shape[1]).index_copy(0, batch["slot"], emb)
    out, _ = net.gru(seq.view(batch["b"], batch["t"], emb.shape[1]))
    return net.heads(out)


def nll(logits, target):
    return -torch.log_softmax(logits, -1).gather(-1, target.unsqueeze(-1)).squeeze(-1)


def loss_of(heads, batch, acting_targets):
    action, target, end = heads
    valid = batch["valid"]
    count = valid.sum()
    vn = valid.unsqueeze(-1)
    n = batch["action"].shape[2]
    if acting_targets:  # the scene network's pointer: the entities that act
        acting = vn * batch["action"].gt(0).float()
        target_loss = (nll(target, batch["target"]) * acting).sum() / acting.sum().clamp_min(1)
    else:
        target_loss = (nll(target, batch["target"]) * vn).sum() / (count * n)
    return ((nll(action, batch["action"]) * vn).sum() / (count * n) + target_loss
            + (nll(end, batch["end"]) * valid).sum() / count)


def accuracy(net, batch):
    with torch.no_grad():
        net.eval()
        action, target, end = run(net, batch)
        act, tgt, e = action.argmax(-1), target.argmax(-1), end.argmax(-1)
        entity_ok = act.eq(batch["action"]) & (batch["action"].eq(0) | tgt.eq(batch["target"]))
        ok = e.eq(batch["end"]) & (batch["end"].eq(1) | entity_ok.all(-1))
        return float((ok.float() * batch["valid"]).sum() / batch["valid"].sum())


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mode", choices=["train", "decision"])
    p.add_argument("tensors")
    p.add_argument("--epochs", type=int, default=30)
    p.add_argument("--batch", type=int, default=8)
    p.add_argument("--lr", type=float, default=5e-3)
    p.add_argument("--heads", type=int, default=2)
    p.add_argument("--head-channels", type=int, default=16)
    p.add_argument("--gru-hidden", type=int, default=64)
    p.add_argument("--identity-dim", type=int, default=8)
    p.add_argument("--dropout", type=float, default=0.1)
    p.add_argument("--head-hidden", type=int, default=32)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--history", type=int, default=6)
    p.add_argument("--repeats", type=int, default=200)
    p.add_argument("--same-shapes", metavar="WEIGHTS",
                   help="a C++ model's weights.pt: refuse to run unless the parameters have the same shapes")
    a = p.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(a.seed)
    meta, mask, seqs = read_tensors(a.tensors)
    scene = meta.get("variant") == "scene"
    net = SceneNetwork(meta, mask, a, seqs[0]["rel"].shape[-1]) if scene else Network(meta, mask, a)
    if a.same_shapes:  # names differ (layers.0 / layer0): the sorted shapes must agree
        theirs = sorted(tuple(p.shape) for p in torch.jit.load(a.same_shapes).parameters())
        ours = sorted(tuple(p.shape) for p in net.parameters())
        if theirs != ours:
            raise SystemExit(f"not the same network: parameter shapes {ours} here, {theirs} in {a.same_shapes}")
    if a.mode == "train":
        adam = torch.optim.Adam(net.parameters(), lr=a.lr)
        rng = random.Random(a.seed)
        order = list(range(len(seqs)))
        everything = collate(seqs, order)
        losses, accs = [], []
        start = time.perf_counter()
        for _ in range(a.epochs):
            rng.shuffle(order)
            net.train()
            total, batches = 0.0, 0
            for i in range(0, len(order), a.batch):
                batch = collate(seqs, order[i:i + a.batch])
                adam.zero_grad()
                loss = loss_of(run(net, batch), batch, scene)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
                adam.step()
                total += loss.item()
                batches += 1
            losses.append(total / batches)
            accs.append(accuracy(net, everything))
        seconds = time.perf_counter() - start
        print(json.dumps({"epochs": a.epochs, "seconds": seconds, "ms_per_epoch": 1000 * seconds / a.epochs,
                          "final_loss": losses[-1], "final_step_accuracy": accs[-1],
                          "relative_features": int(getattr(net, "relative", True))}))
    else:
        net.eval()
        x = seqs[0]["x"][: a.history]
        rel = seqs[0]["rel"][: a.history] if scene else None
        times = []
        with torch.no_grad():
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                if scene:
                    nodes = net.encode(x, rel)
                    out, _ = net.gru(nodes.mean(1).unsqueeze(0))
                    action, target, end = net.heads(nodes[-1], rel[-1], out[0, -1])
                else:
                    emb = net.encode(x)
                    out, _ = net.gru(emb.unsqueeze(0))
                    action, target, end = net.heads(out[0, -1])
                pa, pt, pe = torch.softmax(action, -1), torch.softmax(target, -1), torch.softmax(end, -1)
                pa.argmax(-1).tolist(), pt.argmax(-1).tolist(), float(pe[1])
                times.append(time.perf_counter() - t0)
        times.sort()
        print(json.dumps({"repeats": a.repeats, "median_ms": 1000 * times[len(times) // 2]}))


if __name__ == "__main__":
    main()
