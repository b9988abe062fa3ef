#!/usr/bin/python3
"""Draw a task directory's demonstrations: each entity's path coloured by step,
start (circle) and end (square) marked, goals as stars.

usage: scripts/plot_task.py TASKDIR --out FILE.png [--max-demos N]
"""
import argparse
import csv
import glob
import os
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import yaml  # noqa: E402


def load(taskdir):
    path = os.path.join(taskdir, "task.yaml")
    try:
        with open(path) as f:
            spec = yaml.safe_load(f)
        entities = [(e["name"], e["kind"]) for e in spec["entities"]]
    except (OSError, yaml.YAMLError, KeyError, TypeError) as e:
        sys.exit(f"plot_task: {path}: cannot read the task ({e}); run `ddace validate {taskdir}`")
    demos = []
    for csv_path in sorted(glob.glob(os.path.join(taskdir, "demos", "*.csv"))):
        with open(csv_path, newline="") as f:
            demos.append((csv_path, list(csv.DictReader(f))))
    if not demos:
        sys.exit(f"plot_task: {taskdir}/demos: no demonstrations")
    return spec.get("name", taskdir), entities, demos


def steps_of(rows, names):
    """Step index per row, following the spec's keyframe rule (-1 before the first)."""
    def labels(r):
        return tuple((r.get(n + ".action", "") or "", r.get(n + ".target", "") or "")
                     if (r.get(n + ".action", "") or "") not in ("", "idle") else ("", "")
                     for n in names)
    step, prev, out = -1, tuple(("", "") for _ in names), []
    for r in rows:
        cur = labels(r)
        if any(a for a, _ in cur) and cur != prev:
            step += 1
        out.append((step, cur))
        prev = cur
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("taskdir")
    ap.add_argument("--out", required=True)
    ap.add_argument("--max-demos", type=int, default=6)
    a = ap.parse_args()
    name, entities, demos = load(a.taskdir)
    names = [n for n, _ in entities]
    shown = demos[: a.max_demos]
    cols = min(3, len(shown))
    rows_n = (len(shown) + cols - 1) // cols
    fig, axes = plt.subplots(rows_n, cols, figsize=(4.2 * cols, 4.2 * rows_n), squeeze=False)
    cmap = plt.get_cmap("tab10")
    for ax, (path, rows) in zip(axes.flat, shown):
        info = steps_of(rows, names)
        nsteps = max(s for s, _ in info) + 1
        for ei, (n, kind) in enumerate(entities):
            xs = [float(r[n + ".x"]) for r in rows]
            ys = [float(r[n + ".y"]) for r in rows]
            if kind == "goal":
                ax.plot(xs[0], ys[0], "*", color="k", ms=14)
            else:
                ax.plot(xs[0], ys[0], "o", color="0.3", ms=6)
                ax.plot(xs[-1], ys[-1], "s", color="0.3", ms=5, mfc="none")
            ax.annotate(n, (xs[0], ys[0]), textcoords="offset points", xytext=(4, 4), fontsize=8)
            for k in range(nsteps):
                idx = [i for i, (s, lab) in enumerate(info) if s == k and lab[ei][0]]
                if len(idx) > 1:
                    ax.plot([xs[i] for i in idx], [ys[i] for i in idx], "-", color=cmap(k % 10), lw=1.6,
                            label=f"step {k + 1}" if ei == 0 or True else None)
        handles = [plt.Line2D([], [], color=cmap(k % 10), lw=2) for k in range(nsteps)]
        ax.legend(handles, [f"step {k + 1}" for k in range(nsteps)], fontsize=6, loc="best")
        ax.set_title(os.path.basename(path), fontsize=9)
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(shown):]:
        ax.axis("off")
    fig.suptitle(f"{name}: {len(demos)} demonstrations ({len(shown)} shown)")
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    fig.savefig(a.out, dpi=110)
    print(f"plot_task: wrote {a.out}")


if __name__ == "__main__":
    main()
