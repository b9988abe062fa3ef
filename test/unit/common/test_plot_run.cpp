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
