#!/usr/bin/python3
"""Draw, for every motion primitive of a model, the demonstrated test segments and the
generated mean path with a +-2 sigma band, retargeted to each test demonstration's start
and goal. One PNG per primitive key: DIR/<entity>_<action>_<target>.png.

usage: scripts/plot_paths.py MODELDIR TASKDIR --out DIR [--max-segments N] [--ddace PATH]

The paths come from `ddace path MODELDIR --demos TASKDIR --csv ...` (the same code that
serves the robots), so the figure shows exactly what would be executed.
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile
from collections import defaultdict

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))


def band(xs, ys, sd, k=2.0):
    """Polygon of the path offset by +-k*sd along its normals."""
    left, right = [], []
    n = len(xs)
    for i in range(n):
        a, b = max(i - 1, 0), min(i + 1, n - 1)
        dx, dy = xs[b] - xs[a], ys[b] - ys[a]
        norm = math.hypot(dx, dy) or 1.0
        nx, ny = -dy / norm, dx / norm
        left.append((xs[i] + k * sd[i] * nx, ys[i] + k * sd[i] * ny))
        right.append((xs[i] - k * sd[i] * nx, ys[i] - k * sd[i] * ny))
    return left + right[::-1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", metavar="MODELDIR")
    ap.add_argument("taskdir", metavar="TASKDIR")
    ap.add_argument("--out", required=True, metavar="DIR")
    ap.add_argument("--max-segments", type=int, default=6, metavar="N",
                    help="test segments drawn per primitive (default 6; the FD in the title uses all)")
    ap.add_argument("--ddace", default=os.path.join(REPO, "scripts", "ddace"), help="the ddace tool")
    args = ap.parse_args()

    os.makedirs(args.out, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        table = os.path.join(tmp, "paths.csv")
        run = subprocess.run([args.ddace, "path", args.model, "--demos", args.taskdir, "--csv", table],
                             capture_output=True, text=True)
        if run.returncode != 0:
            sys.exit("plot_paths: ddace path failed:\n" + run.stderr + run.stdout)
        fd = {}
        for line in run.stdout.splitlines():
            parts = line.split()
            if len(parts) == 3 and ":" in parts[0]:
                try:
                    fd[parts[0]] = float(parts[2])
                except ValueError:
                    pass
        # key -> (demo, segment) -> kind -> rows
        paths = defaultdict(lambda: defaultdict(lambda: defaultdict(list)))
        source = {}
        with open(table, newline="") as f:
            for r in csv.DictReader(f):
                paths[r["key"]][(r["demo"], r["segment"])][r["kind"]].append(
                    (float(r["x"]), float(r["y"]), float(r["stddev"])))
                source[r["key"]] = r["source_key"]
    if not paths:
        sys.exit(f"plot_paths: {args.taskdir} has no motion segments")

    cmap = plt.get_cmap("tab10")
    for key, segments in sorted(paths.items()):
        fig, ax = plt.subplots(figsize=(6, 6))
        for i, (_, kinds) in enumerate(sorted(segments.items())[:max(args.max_segments, 1)]):
            c = cmap(i % 10)
            demo, gen = kinds["demo"], kinds["generated"]
            xs, ys, sd = zip(*gen)
            ax.add_patch(plt.Polygon(band(xs, ys, sd), closed=True, facecolor=c, alpha=0.18, edgecolor="none"))
            ax.plot(xs, ys, "-", color=c, lw=1.8, label="generated mean" if i == 0 else None)
            ax.plot([p[0] for p in demo], [p[1] for p in demo], "--", color=c, lw=1.0,
                    label="demonstrated (test)" if i == 0 else None)
            ax.plot(demo[0][0], demo[0][1], "o", color=c, ms=4)
            ax.plot(demo[-1][0], demo[-1][1], "s", color=c, ms=4)
        title = f"{key}: {min(len(segments), max(args.max_segments, 1))} of {len(segments)} test segments"
        if key in fd:
            title += f", mean normalised FD {fd[key]:.4f}"
        if source.get(key, key) != key:
            title += f"\n(never demonstrated: fell back to {source[key]})"
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("x (m, table frame)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8, title="band: +-2 sigma", title_fontsize=8)
        out = os.path.join(args.out, key.replace(":", "_") + ".png")
        fig.savefig(out, dpi=110, bbox_inches="tight")
        plt.close(fig)
        print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
