#!/usr/bin/python3
"""Draw one run of the execution graph as one view of the whole table: every body's
footprint where it started (dashed) and where it ended (solid), every planned path (thin,
with its +-2 sigma band) and every executed path, one colour per entity (ENTITY_COLOURS),
the goals as flat prints, the objects hatched, and the run's closest approach between two
bodies (with its clearance): red only when that pair collided, else grey; collisions are
listed in the title. No label is drawn over another: one that would be is moved to the
nearest free spot around its point, with a thin line back to it (a box carried by its
robot, on its goal). Below it, the run in time: one row per robot, its segments as bars,
and when it waited and for whom (hatched: from when it stood until its next segment went
out, released by the segment of another entity that ended last before then). Reads the
run.json that execution_monitor_node writes into the run directory.

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


def waits(segments, gap_s=0.05):
    """(robot, from_s, to_s, released_by) for every time a robot stood longer than gap_s
    before its next segment went out, waiting for another entity's segment to end: the one
    that ended last before then (in steps, the slowest of the step before; in async, its
    predecessor)."""
    ended = [s for s in segments if s.get("ended_s") is not None]
    per_robot = {}
    for s in sorted(segments, key=lambda s: s["sent_s"]):
        if s.get("kind") == "robot":
            per_robot.setdefault(s["entity"], []).append(s)
    out = []
    for robot, segs in per_robot.items():
        idle = 0.0  # the first decision
        for s in segs:
            released = [o for o in ended if o["entity"] != robot and o["ended_s"] <= s["sent_s"] + 1e-6]
            if released and s["sent_s"] - idle > gap_s:
                by = max(released, key=lambda o: o["ended_s"])
                if by["ended_s"] > idle:
                    out.append((robot, idle, s["sent_s"], by["key"]))
            idle = s["ended_s"] if s.get("ended_s") is not None else s["sent_s"]
    return out


def timeline(ax, segments, colour):
    """One row per robot: its segments, and when it waited and for whom."""
    robots = sorted({s["entity"] for s in segments if s.get("kind") == "robot"})
    row = {r: i for i, r in enumerate(robots)}
    end = max([s["sent_s"] for s in segments] + [s["ended_s"] for s in segments if s.get("ended_s") is not None]
              + [1.0])
    for s in segments:
        if s["entity"] not in row:
            continue
        stop = s["ended_s"] if s.get("ended_s") is not None else end
        ax.broken_barh([(s["sent_s"], max(stop - s["sent_s"], 1e-3))], (row[s["entity"]] - 0.3, 0.6),
                       color=colour.get(s["entity"], "grey"), alpha=0.8)
    for robot, since, until, by in waits(segments):
        ax.broken_barh([(since, until - since)], (row[robot] - 0.3, 0.6), facecolor="none", edgecolor="grey",
                       hatch="///", lw=0.6)
        ax.annotate("waits %.1fs for %s" % (until - since, by), ((since + until) / 2, row[robot]), fontsize=7,
                    ha="center", va="center", bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.8))
    ax.set_yticks(range(len(robots)))
    ax.set_yticklabels(robots)
    ax.set_ylim(-0.6, max(len(robots), 1) - 0.4)
    ax.invert_yaxis()
    ax.set_xlabel("time since the first decision (s); hatched: waiting")
    ax.grid(axis="x", alpha=0.3)


def overlaps(box, placed):
    return sum(max(0.0, min(box.x1, p.x1) - max(box.x0, p.x0)) * max(0.0, min(box.y1, p.y1) - max(box.y0, p.y0))
               for p in placed)


def place_labels(fig, ax, labels):
    """Draws the labels in order, each where it overlaps no label drawn before it: at its own
    offset if free, else at the nearest free spot around its point (with a thin line back to
    it), else where it overlaps least. Returns the annotations."""
    renderer = fig.canvas.get_renderer()
    placed, drawn = [], []
    for label in labels:
        dx, dy = label["offset"]
        tries = [(dx, dy)] + [(dx + k * math.cos(a), dy + k * math.sin(a)) for k in (10, 20, 32, 48)
                              for a in [i * math.pi / 4 for i in (2, 6, 0, 4, 1, 3, 5, 7)]]
        best = None
        for off in tries:
            note = ax.annotate(label["text"], label["xy"], xytext=off, textcoords="offset points",
                               fontsize=label["fontsize"], color=label["color"], ha=label["ha"], va=label["va"],
                               bbox=label.get("bbox"))
            box = note.get_window_extent(renderer).expanded(1.05, 1.1)
            cost = overlaps(box, placed)
            if best is None or cost < best[0]:
                if best is not None:
                    best[1].remove()
                best = (cost, note, box, off)
            else:
                note.remove()
            if cost == 0:
                break
        cost, note, box, off = best
        if off != (dx, dy):
            ax.annotate("", label["xy"], xytext=off, textcoords="offset points",
                        arrowprops=dict(arrowstyle="-", color=label["color"], lw=0.4, alpha=0.6))
        placed.append(box)
        drawn.append(note)
    return drawn


ALARM, INFO = "crimson", "dimgrey"  # a collision; the closest approach when it was none
# One colour per entity, told apart at a glance: the first eight differ in hue, the next four
# in lightness as well; none is like ALARM or INFO. Robots take
# the first, then objects, then goals, so robots and what they bring never share a hue in a
# task of eight entities or fewer; past twelve the colours repeat.
ENTITY_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#bcbd22", "#17becf", "#e377c2", "#137e6d",
                  "#000080", "#836539", "#ac4f06", "#6a6e09"]
KIND_ORDER = ("robot", "object", "goal")


def entity_colours(bodies, names):
    """Each entity's colour: robots first, then objects, then goals, in the task's order."""
    kind = {b["name"]: b.get("kind") for b in bodies}
    rank = {k: i for i, k in enumerate(KIND_ORDER)}
    order = sorted(names, key=lambda n: (rank.get(kind.get(n), len(KIND_ORDER)), names.index(n)))
    return {n: ENTITY_COLOURS[i % len(ENTITY_COLOURS)] for i, n in enumerate(order)}


def draw(run):
    """The figure of one run and its labels (as placed)."""
    name_labels, time_labels = [], []  # placed last: names first, then the paths' start times
    bodies = run.get("bodies") or []
    names = [b["name"] for b in bodies] or sorted({s["entity"] for s in run["segments"]})
    colour = entity_colours(bodies, names)
    fig, (ax, tl) = plt.subplots(2, 1, figsize=(9, 11.5), gridspec_kw={"height_ratios": [4, 1]})
    timeline(tl, run["segments"], colour)
    for seg in run["segments"]:
        c = colour.get(seg["entity"], "grey")
        planned = seg.get("planned") or []
        executed = seg.get("executed") or []
        if len(planned) >= 2:
            ax.fill(*zip(*band(planned, seg.get("stddev_m") or [])), color=c, alpha=0.12, lw=0)
            ax.plot(*zip(*planned), color=c, lw=0.8, ls="--")
        if executed:
            ax.plot(*zip(*executed), color=c, lw=1.6)
            time_labels.append(dict(text="t=%.1fs" % seg["sent_s"], xy=executed[0], offset=(2, -8), fontsize=6,
                                    color=c, ha="left", va="top"))
    for b in bodies:
        c = colour[b["name"]]
        r = b.get("radius_m", 0.02)
        flat = not b.get("obstacle", True)
        for key, style in (("start", "--"), ("end", "-")):
            if key not in b:
                continue
            if flat:
                ax.add_patch(Circle(b[key], r, color=c, alpha=0.25, lw=0))
            else:  # an object's footprint hatched, a robot's plain: the kind at a glance
                ax.add_patch(Circle(b[key], r, fill=False, ec=c, ls=style, lw=1.2,
                                    hatch="////" if b.get("kind") == "object" else None))
        if "end" in b:
            # Goals are labelled below their print, bodies above theirs: a box on its goal
            # keeps both names legible.
            below = flat
            name_labels.append(dict(text=b["name"], xy=b["end"], offset=(0, -(r * 400 + 2) if below else (r * 400 + 2)),
                              fontsize=8, color="black", ha="center", va="top" if below else "bottom",
                              bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=c, alpha=0.8, lw=0.6)))
    near = run.get("closest")
    if near:
        # Red is for an alarm only: the closest pair collided. Otherwise the closest approach
        # is information (grey).
        hits = run.get("collisions") or []
        alarm = any({h["a"], h["b"]} == {near["a"], near["b"]} for h in hits)
        tone = ALARM if alarm else INFO
        (xa, ya), (xb, yb) = near["at_a"], near["at_b"]
        ax.plot([xa, xb], [ya, yb], color=tone, lw=2.5 if alarm else 1.2, ls="-" if alarm else ":")
        for name, at in ((near["a"], near["at_a"]), (near["b"], near["at_b"])):
            r = next((b.get("radius_m", 0.02) for b in bodies if b["name"] == name), 0.02)
            ax.add_patch(Circle(at, r, fill=False, ec=tone, lw=1.5 if alarm else 0.8, ls="-" if alarm else ":"))
        name_labels.append(dict(text="%s: %s-%s %.1f cm at t=%.1fs" % ("collision" if alarm else "closest approach",
                                                                 near["a"], near["b"], 100 * near["clearance_m"],
                                                                 near["time_s"]),
                          xy=((xa + xb) / 2, (ya + yb) / 2), offset=(6, 6), fontsize=8, color=tone, ha="left",
                          va="bottom"))
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
    fig.set_dpi(110)
    return fig, place_labels(fig, ax, name_labels + time_labels)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        run = json.load(f)
    fig, _ = draw(run)
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
