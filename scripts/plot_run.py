#!/usr/bin/python3
"""Draw one run of the execution graph as one view of the whole table: every body's
footprint where it started (dashed) and where it ended (solid), every planned path (thin,
with its +-2 sigma band) and every executed path, one colour per entity, the goals as flat
prints, and the run's closest approach between two bodies (with its clearance): red
only when that pair collided, else grey; collisions are listed in the title. Reads the run.json that
execution_monitor_node writes into the run directory.

usage: scripts/plot_run.py RUN_DIR/run.json OUT.png
"""
import json
import math
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402


def band(points, sd, k=2.0):
    """Polygon of the path offset by +-k*sd along its normals."""
    left, right = [], []
    n = len(points)
    for i, (x, y) in enumerate(points):
        j, h = (i + 1, i) if i + 1 < n else (i, i - 1)
        dx, dy = points[j][0] - points[h][0], points[j][1] - points[h][1]
        d = math.hypot(dx, dy) or 1.0
        nx, ny = -dy / d, dx / d
        s = k * (sd[i] if i < len(sd) else 0.0)
        left.append((x + s * nx, y + s * ny))
        right.append((x - s * nx, y - s * ny))
    return left + right[::-1]


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        run = json.load(f)
    bodies = run.get("bodies") or []
    names = [b["name"] for b in bodies] or sorted({s["entity"] for s in run["segments"]})
    cmap = plt.get_cmap("tab20")
    colour = {n: cmap(i % 20) for i, n in enumerate(names)}
    fig, ax = plt.subplots(figsize=(9, 9))
    for seg in run["segments"]:
        c = colour.get(seg["entity"], "grey")
        planned = seg.get("planned") or []
        executed = seg.get("executed") or []
        if len(planned) >= 2:
            ax.fill(*zip(*band(planned, seg.get("stddev_m") or [])), color=c, alpha=0.12, lw=0)
            ax.plot(*zip(*planned), color=c, lw=0.8, ls="--")
        if executed:
            ax.plot(*zip(*executed), color=c, lw=1.6)
            ax.annotate("t=%.1fs" % seg["sent_s"], executed[0], fontsize=6, xytext=(2, -8),
                        textcoords="offset points", color=c)
    for b in bodies:
        c = colour[b["name"]]
        r = b.get("radius_m", 0.02)
        flat = not b.get("obstacle", True)
        for key, style in (("start", "--"), ("end", "-")):
            if key not in b:
                continue
            if flat:
                ax.add_patch(Circle(b[key], r, color=c, alpha=0.25, lw=0))
            else:
                ax.add_patch(Circle(b[key], r, fill=False, ec=c, ls=style, lw=1.2))
        if "end" in b:
            # Goals are labelled below their print, bodies above theirs: a box on its goal
            # keeps both names legible.
            below = flat
            ax.annotate(b["name"], b["end"], fontsize=8, ha="center", va="top" if below else "bottom",
                        xytext=(0, -(r * 400 + 2) if below else (r * 400 + 2)), textcoords="offset points",
                        color="black", bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=c, alpha=0.8, lw=0.6))
    near = run.get("closest")
    if near:
        # Red is for an alarm only: the closest pair collided. Otherwise the closest approach
        # is information (grey).
        hits = run.get("collisions") or []
        alarm = any({h["a"], h["b"]} == {near["a"], near["b"]} for h in hits)
        tone = "red" if alarm else "dimgrey"
        (xa, ya), (xb, yb) = near["at_a"], near["at_b"]
        ax.plot([xa, xb], [ya, yb], color=tone, lw=2.5 if alarm else 1.2, ls="-" if alarm else ":")
        for name, at in ((near["a"], near["at_a"]), (near["b"], near["at_b"])):
            r = next((b.get("radius_m", 0.02) for b in bodies if b["name"] == name), 0.02)
            ax.add_patch(Circle(at, r, fill=False, ec=tone, lw=1.5 if alarm else 0.8, ls="-" if alarm else ":"))
        ax.annotate("%s: %s-%s %.1f cm at t=%.1fs" % ("collision" if alarm else "closest approach", near["a"],
                                                        near["b"], 100 * near["clearance_m"], near["time_s"]),
                    ((xa + xb) / 2, (ya + yb) / 2), fontsize=8, color=tone, xytext=(6, 6),
                    textcoords="offset points")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(alpha=0.3)
    hits = run.get("collisions") or []
    collided = ", ".join("%s-%s at %.1fs" % (c["a"], c["b"], c["time_s"]) for c in hits[:6])
    fig.suptitle("%s: %s; %d collision%s%s\nfootprints: dashed at the start, solid at the end; paths: dashed "
                 "planned, solid executed" % (run["task"], run["state"], len(hits), "" if len(hits) == 1 else "s",
                                              (" (" + collided + (", ..." if len(hits) > 6 else "") + ")")
                                              if hits else ""), fontsize=9)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
