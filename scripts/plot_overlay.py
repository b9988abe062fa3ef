#!/usr/bin/python3
"""Draw one closed-loop trial: demonstrated segments (grey) and generated paths (colour).

usage: scripts/plot_overlay.py OVERLAY.csv --out FILE.png [--title T]
OVERLAY.csv (written by `ddace table`): kind,token,index,x,y with kind
"demonstrated" or "generated".
"""
import argparse
import csv
import os
import sys
from collections import defaultdict

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("overlay")
    ap.add_argument("--out", required=True)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    paths = defaultdict(list)
    try:
        with open(a.overlay, newline="") as f:
            for line, row in enumerate(csv.DictReader(f), start=2):
                try:
                    paths[(row["kind"], row["token"])].append((float(row["x"]), float(row["y"])))
                except (KeyError, ValueError) as e:
                    sys.exit(f"plot_overlay: {a.overlay}:{line}: bad row ({e})")
    except OSError as e:
        sys.exit(f"plot_overlay: {e}")
    if not paths:
        sys.exit(f"plot_overlay: {a.overlay}: no paths")
    fig, ax = plt.subplots(figsize=(5, 5))
    cmap = plt.get_cmap("tab10")
    tokens = sorted({t for _, t in paths})
    for i, token in enumerate(tokens):
        demo = paths.get(("demonstrated", token))
        gen = paths.get(("generated", token))
        if demo:
            ax.plot(*zip(*demo), "-", color="0.6", lw=4, alpha=0.6)
        if gen:
            ax.plot(*zip(*gen), "-", color=cmap(i % 10), lw=1.5, label=token)
            ax.plot(*gen[0], "o", color=cmap(i % 10), ms=5)
            ax.plot(*gen[-1], "s", color=cmap(i % 10), ms=5, mfc="none")
    ax.plot([], [], "-", color="0.6", lw=4, alpha=0.6, label="demonstrated")
    ax.legend(fontsize=7, loc="best")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.set_title(a.title or os.path.basename(a.overlay))
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    fig.savefig(a.out, dpi=110)
    print(f"plot_overlay: wrote {a.out}")


if __name__ == "__main__":
    main()
