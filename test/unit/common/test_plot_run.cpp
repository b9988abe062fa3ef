// scripts/plot_run.py (a run's paths.png): the names of bodies that end on or against each
// other (a box carried in front of its robot, on its goal, a second robot queued beside)
// and the paths' start times stay legible: no two labels drawn over each other.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "../common/run_tool.h"
#include "ddace/common/repository.h"

namespace fs = std::filesystem;

TEST(PlotRun, LabelsOfBodiesEndingTogetherDoNotOverlap) {
  const fs::path scripts = ddace::findRepository("", {"scripts/plot_run.py"}) / "scripts";
  const std::string dir = ::testing::TempDir() + "/ddace_plot_run";
  fs::create_directories(dir);
  std::ofstream(dir + "/check.py") << R"(
import sys
sys.path.insert(0, sys.argv[1])
import plot_run
seg = lambda e, t, pts: {"entity": e, "kind": "robot" if e[0] == "R" else "object", "key": e + ":move:G1",
                         "sent_s": t, "ended_s": t + 1.0, "planned": pts, "executed": pts, "stddev_m": [0.0] * len(pts)}
run = {"task": "fetch2", "state": "finished", "collisions": [],
       "closest": {"a": "R1", "b": "B1", "at_a": [0.50, 0.50], "at_b": [0.535, 0.50], "clearance_m": 0.001,
                   "time_s": 2.0},
       "bodies": [{"name": "R1", "radius_m": 0.02, "start": [0.2, 0.5], "end": [0.50, 0.50]},
                  {"name": "B1", "radius_m": 0.015, "start": [0.3, 0.3], "end": [0.535, 0.50]},
                  {"name": "G1", "radius_m": 0.02, "obstacle": False, "start": [0.535, 0.50], "end": [0.535, 0.50]},
                  {"name": "R2", "radius_m": 0.02, "start": [0.8, 0.5], "end": [0.50, 0.54]}],
       "segments": [seg("R1", 0.0, [[0.2, 0.5], [0.3, 0.3]]), seg("R1", 1.0, [[0.3, 0.3], [0.5, 0.5]]),
                    seg("R2", 1.0, [[0.8, 0.5], [0.3, 0.3]]), seg("R2", 2.0, [[0.3, 0.3], [0.5, 0.54]]),
                    seg("B1", 1.0, [[0.3, 0.3], [0.535, 0.5]])]}
fig, notes = plot_run.draw(run)
renderer = fig.canvas.get_renderer()
boxes = [(n.get_text(), n.get_window_extent(renderer)) for n in notes]
print("labels:", len(boxes))
for i, (a, p) in enumerate(boxes):
    for b, q in boxes[i + 1:]:
        if p.overlaps(q):
            print("overlap: %s / %s" % (a, b))
)";
  const ddace::test::ToolRun run =
      ddace::test::runShell("/usr/bin/python3 '" + dir + "/check.py' '" + scripts.string() + "'");
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("labels: 10"), std::string::npos) << run.out;  // 4 names, the closest approach, 5 times
  EXPECT_EQ(run.out.find("overlap:"), std::string::npos) << run.out;
}

// Every entity's colour is told apart from every other's at a glance (the first eight by hue
// alone: a goal light-filled beside a robot's outline shows hue, not lightness) and from the
// alarm's red and the closest approach's grey, for Task 4 (4 robots, a goal), fetch2 (2
// robots, a box, a goal), 5 robots with a box and 2 goals, and 12 entities. Read from the
// names' labels as drawn, whose frames take their entity's colour.
TEST(PlotRun, EveryEntityHasAColourOfItsOwn) {
  const fs::path scripts = ddace::findRepository("", {"scripts/plot_run.py"}) / "scripts";
  const std::string dir = ::testing::TempDir() + "/ddace_plot_run_colours";
  fs::create_directories(dir);
  std::ofstream(dir + "/check.py") << R"(
import math, sys
sys.path.insert(0, sys.argv[1])
import matplotlib.colors as mc
import plot_run

def lch(c):  # CIE L*C*h (D65)
    rgb = [v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4 for v in mc.to_rgb(c)]
    xyz = [sum(m * v for m, v in zip(row, rgb)) / n for row, n in zip(
        [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]], [0.95047, 1.0, 1.08883])]
    f = [t ** (1 / 3) if t > 0.008856 else 7.787 * t + 16 / 116 for t in xyz]
    a, b = 500 * (f[0] - f[1]), 200 * (f[1] - f[2])
    return 116 * f[1] - 16, math.hypot(a, b), math.degrees(math.atan2(b, a)) % 360

def hue_apart(p, q):
    (_, cp, hp), (_, cq, hq) = lch(p), lch(q)
    return min(cp, cq) > 20 and abs((hp - hq + 180) % 360 - 180) >= 20

def apart(p, q):
    return hue_apart(p, q) or abs(lch(p)[0] - lch(q)[0]) >= 20 or max(lch(p)[1], lch(q)[1]) > 30 > 10 > min(lch(p)[1], lch(q)[1])

def scene(kinds):
    bodies = [{"name": n, "kind": k, "radius_m": 0.02, "obstacle": k != "goal", "start": [0.1 * i, 0.1],
               "end": [0.1 * i, 0.5 + 0.05 * (i % 2)]} for i, (n, k) in enumerate(kinds)]
    return {"task": "t", "state": "finished", "collisions": [], "bodies": bodies,
            "segments": [{"entity": kinds[0][0], "kind": "robot", "key": "k", "sent_s": 0.0, "ended_s": 1.0,
                          "planned": [], "executed": [[0.0, 0.1], [0.0, 0.5]], "stddev_m": []}]}

R = lambda n: [("R%d" % i, "robot") for i in range(1, n + 1)]
scenes = {"task4": R(4) + [("G1", "goal")], "fetch2": R(2) + [("G1", "goal"), ("B1", "object")],
          "five": R(5) + [("G1", "goal"), ("B1", "object"), ("G2", "goal")],
          "twelve": R(6) + [("B1", "object"), ("B2", "object"), ("G1", "goal"), ("G2", "goal"), ("G3", "goal"),
                            ("G4", "goal")]}
for name, kinds in scenes.items():
    fig, notes = plot_run.draw(scene(kinds))
    colour = {n.get_text(): mc.to_hex(n.get_bbox_patch().get_edgecolor()) for n in notes
              if n.get_text() in dict(kinds)}
    print(name, "colours:", len(colour))
    rule = hue_apart if len(kinds) <= 8 else apart
    for i, (a, ca) in enumerate(sorted(colour.items())):
        for b, cb in sorted(colour.items())[i + 1:]:
            if not rule(ca, cb):
                print("alike: %s %s %s / %s %s" % (name, a, ca, b, cb))
        for alarm in (plot_run.ALARM, plot_run.INFO):
            if not hue_apart(ca, alarm) and not apart(ca, alarm):
                print("alarm-like: %s %s %s" % (name, a, ca))
)";
  const ddace::test::ToolRun run =
      ddace::test::runShell("/usr/bin/python3 '" + dir + "/check.py' '" + scripts.string() + "'");
  ASSERT_EQ(run.status, 0) << run.out;
  for (const std::string line : {"task4 colours: 5", "fetch2 colours: 4", "five colours: 8", "twelve colours: 12"})
    EXPECT_NE(run.out.find(line), std::string::npos) << run.out;
  EXPECT_EQ(run.out.find("alike:"), std::string::npos) << run.out;
  EXPECT_EQ(run.out.find("alarm-like:"), std::string::npos) << run.out;
}
