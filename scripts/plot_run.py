#!/usr/bin/python3
"""Draw one run of the execution graph: per robot, the planned paths (with their +-2 sigma
band) against the positions the robot actually passed through, with the decision times
marked along the executed paths. Reads the run.json that execution_monitor_node writes
into the run directory.

usage: scripts/plot_run.py RUN_DIR/run.json OUT.png
"""
import json
import math
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


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
    robots = sorted({s["entity"] for s in run["segments"] if s.get("kind") == "robot"})
    if not robots:
        robots = sorted({s["entity"] for s in run["segments"]})
    cols = max(1, min(4, len(robots)))
    rows = max(1, math.ceil(len(robots) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 4 * rows), squeeze=False)
    for ax in axes.flat:
        ax.set_visible(False)
    for ax, robot in zip(axes.flat, robots):
        ax.set_visible(True)
        for seg in (s for s in run["segments"] if s["entity"] == robot):
            planned = seg.get("planned") or []
            executed = seg.get("executed") or []
            if len(planned) >= 2:
                poly = band(planned, seg.get("stddev_m") or [])
                ax.fill(*zip(*poly), color="tab:blue", alpha=0.2, lw=0)
                ax.plot(*zip(*planned), color="tab:blue", lw=1.2, label="planned (±2σ)")
            if executed:
                ax.plot(*zip(*executed), color="tab:orange", lw=1.2, label="executed")
                # The step's decision: where the robot was when its segment went out.
                ax.plot(*executed[0], marker="o", color="black", ms=4)
                ax.annotate("t=%.1fs" % seg["sent_s"], executed[0], fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
            ax.plot(*seg["goal"], marker="x", color="tab:green", ms=7)
        ax.set_title(robot)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        handles, labels = ax.get_legend_handles_labels()
        uniq = dict(zip(labels, handles))
        ax.legend(uniq.values(), uniq.keys(), fontsize=7, loc="best")
    decisions = ", ".join("%.1f" % t for t in run.get("decisions_s", []))
    fig.suptitle("%s: %s (decisions at %s s)" % (run["task"], run["state"], decisions), fontsize=9)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
