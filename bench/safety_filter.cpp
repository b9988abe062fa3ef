// bench_safety_filter: the collision-avoidance safety filter's cost per robot per control
// cycle with 11 robots (exec/safety_filter.h), against the path follower's control law
// (exec/path_follower.h) timed in the same run on the same poses: the unfiltered command.
//
// Scene: 11 Hamsters on a circle of radius 0.2 m, each driving through the centre to the
// opposite side (every robot has every other within the filter's range for most of the
// run: the worst case of crowding), closed loop at 50 Hz with DiffDriveModel unicycles
// (40 ms latency, poses a 30 Hz camera frame old). Each call is timed on the steady clock;
// the medians and 99th percentiles are over every call of every robot in the run.
// Writes docs/bench/safety_filter.md.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <thread>

#include "ddace/common/clock.h"
#include "ddace/common/machine.h"
#include "ddace/exec/diff_drive.h"
#include "ddace/exec/path_follower.h"
#include "ddace/exec/safety_filter.h"
#include "results.h"

using namespace ddace;
using Eigen::Vector2d;

namespace {

constexpr int kRobots = 11;
constexpr double kRadius = 0.022;

double pct(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * (v.size() - 1) + 0.5))];
}

struct Run {
  std::vector<double> follower_us, filter_us;
  double min_gap_m = 1e9, end_s = 0;
  int arrived = 0, deadlocks = 0;
};

Run run(int repeat) {
  exec::DiffDriveParams dp;
  dp.latency_s = 0.04;
  exec::FollowerGains g;
  std::vector<exec::DiffDriveModel> robots;
  std::vector<exec::PathFollower> followers;
  std::vector<exec::SafetyFilter> filters;
  std::vector<std::string> names;
  const Vector2d centre(0.5, 0.5);
  for (int i = 0; i < kRobots; ++i) {
    const double a = 2 * M_PI * i / kRobots + 0.05 * repeat;
    const Vector2d from = centre + 0.2 * Vector2d(std::cos(a), std::sin(a)), to = 2 * centre - from;
    dp.seed = 100 * repeat + i;
    dp.position_noise_m = 0.001;
    robots.emplace_back(dp, exec::Pose2D{from.x(), from.y(), a + M_PI});
    followers.emplace_back(g);
    std::vector<Vector2d> path;
    for (int k = 0; k <= 50; ++k) path.push_back(from + (to - from) * k / 50.0);
    followers.back().setPath({path, {}});
    filters.emplace_back(exec::SafetyParams{}, g.wheel_base_m, g.max_wheel_speed_mps, g.max_turn_rate_radps);
    names.push_back("R" + std::to_string(i + 1));
  }
  Run r;
  std::vector<bool> done(kRobots, false);
  std::vector<exec::Pose2D> seen(kRobots);
  std::vector<exec::SafetyBody> bodies;
  double seen_at = -1;
  for (double t = 0; t < 60; t += 1.0 / dp.rate_hz) {
    if (seen_at < 0 || t - seen_at >= 1.0 / 30 - 1e-9) {
      for (int i = 0; i < kRobots; ++i) seen[i] = robots[i].measuredPose();
      seen_at = t;
    }
    const double age = t - seen_at + 1.0 / 30;
    bool all = true;
    for (int i = 0; i < kRobots; ++i) {
      if (done[i]) {
        robots[i].command({}, robots[i].time());
        continue;
      }
      all = false;
      auto t0 = SteadyClock::now();
      const exec::FollowerOutput f = followers[i].compute(seen[i]);
      r.follower_us.push_back(1e3 * msSince(t0));
      if (f.done) {
        done[i] = true;
        ++r.arrived;
        continue;
      }
      bodies.clear();
      for (int j = 0; j < kRobots; ++j)
        if (j != i) bodies.push_back({names[j], seen[j].position(), kRadius, true, age, false});
      t0 = SteadyClock::now();
      const exec::SafetyCommand c = filters[i].filter(names[i], seen[i], kRadius, age, f.wheels,
                                                      f.progress * followers[i].lengthM(), bodies, "", t);
      r.filter_us.push_back(1e3 * msSince(t0));
      if (c.deadlock) {
        done[i] = true;
        ++r.deadlocks;
      }
      robots[i].command(c.wheels, robots[i].time());
    }
    for (auto& m : robots) m.step();
    for (int i = 0; i < kRobots; ++i)
      for (int j = i + 1; j < kRobots; ++j)
        r.min_gap_m = std::min(
            r.min_gap_m, (robots[i].truePose().position() - robots[j].truePose().position()).norm() - 2 * kRadius);
    r.end_s = t;
    if (all) break;
  }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const auto repo = bench::repositoryFromArgs(argc, argv);
    bench::noOtherOptions(argc, argv, "bench_safety_filter");
    const std::string load = loadAverage();
    Run all;
    std::ostringstream runs;
    for (int k = 0; k < 5; ++k) {
      const Run r = run(k);
      all.follower_us.insert(all.follower_us.end(), r.follower_us.begin(), r.follower_us.end());
      all.filter_us.insert(all.filter_us.end(), r.filter_us.begin(), r.filter_us.end());
      runs << "| " << k << " | " << r.arrived << "/" << kRobots << " | " << r.deadlocks << " | " << std::fixed
           << std::setprecision(1) << r.min_gap_m * 100 << " | " << r.end_s << " |\n";
    }
    const double f50 = pct(all.filter_us, 0.5), f99 = pct(all.filter_us, 0.99);
    const double c50 = pct(all.follower_us, 0.5), c99 = pct(all.follower_us, 0.99);
    std::ostringstream md;
    md << std::fixed;
    md << "# Safety filter: cost per robot per control cycle\n\n"
       << "Written by `bench_safety_filter` (bench/safety_filter.cpp; `ddace bench safety_filter`). Do not edit.\n\n"
       << kRobots << " Hamsters on a circle of radius 0.2 m, each driving through the centre to the opposite side "
       << "(the crowded worst case: every other robot in range), 50 Hz control, 40 ms wheel latency, poses a 30 Hz "
       << "frame old; 5 runs with different starting angles and noise. Reference in the same run: the path "
       << "follower's control law (the unfiltered command) on the same poses. " << std::thread::hardware_concurrency()
       << " cores, 1-minute load average at the start: " << load << ".\n\n"
       << "| per robot per cycle | calls | median (us) | p99 (us) |\n|---|---:|---:|---:|\n"
       << std::setprecision(2) << "| safety filter (" << kRobots - 1 << " neighbours) | " << all.filter_us.size()
       << " | " << f50 << " | " << f99 << " |\n"
       << "| path follower (reference) | " << all.follower_us.size() << " | " << c50 << " | " << c99 << " |\n"
       << "| ratio filter / follower | | " << f50 / c50 << "x | " << f99 / c99 << "x |\n\n"
       << "| run | arrived | deadlocks reported | minimum clearance (cm) | end (s) |\n|---:|---:|---:|---:|---:|\n"
       << runs.str()
       << "\nGoals: < 50 us per robot per control cycle with 11 robots; every robot arrives in every run, no deadlock "
       << "reported, no contact (minimum clearance > 0).\n";
    std::cout << md.str();
    bench::writeResults(repo, "safety_filter", md.str());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "bench_safety_filter: " << e.what() << "\n";
    return 1;
  }
}
