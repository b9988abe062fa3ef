// A demonstration recorded through the camera in which robots stop at contact: generated
// Task 4 with bodies (R1 drives to R3 and stops touching it, R4 stops touching R3 on G1),
// rendered by the synthetic camera and measured by the tracker, every frame, as a person
// would record it. The tracker keeps every robot at contact apart, the end points learned
// from the recording are at contact, and a model trained on it runs: replayed in the
// closed loop with its own paths and end points every motion arrives, and the coordinator,
// sent the recording's steps and seeing the robots where the camera saw them stop, counts
// every motion done.
#include <gtest/gtest.h>

#include <cmath>

#include "ddace/common/repository.h"
#include "ddace/eval/metrics.h"
#include "ddace/exec/coordinator.h"
#include "ddace/exec/replay.h"
#include "ddace/exec/simulator.h"
#include "ddace/gp/primitives.h"
#include "ddace/task/end_point.h"
#include "ddace/tasks/generators.h"
#include "ddace/vision/synthetic_camera.h"
#include "ddace/vision/tracker.h"

using namespace ddace;
using Eigen::Vector2d;

namespace {

std::string repoPath(const std::string& sub) {
  return (findRepository("", {sub}) / sub).string() + "/";
}

/// `truth` as the tracker measures it: every row rendered and tracked (a fresh tracker
/// per recording); labels as the person set them. Counts robot frames in `frames`, those in
/// which the robot was not measured (its pose held) in `unseen`.
task::Demonstration recordThroughCamera(const task::Demonstration& truth, const task::TaskSpec& spec,
                                        const vision::TrackerConfig& config, vision::SyntheticCamera& camera,
                                        int& frames, int& unseen, double& max_error_m) {
  vision::Tracker tracker(config);
  tracker.setCamera(camera.camera());
  task::Demonstration d;
  d.t = truth.t;
  d.labels = truth.labels;
  d.has_label_columns = truth.has_label_columns;
  std::vector<double> yaw(spec.entities.size(), 0.0);
  for (size_t r = 0; r < truth.rows(); ++r) {
    std::vector<vision::TrueEntity> scene;
    for (size_t e = 0; e < spec.entities.size(); ++e) {
      const Vector2d p = truth.positions[r][e];
      if (r > 0 && (p - truth.positions[r - 1][e]).norm() > 1e-4) {
        const Vector2d v = p - truth.positions[r - 1][e];
        yaw[e] = std::atan2(v.y(), v.x());  // a robot faces where it drives
      }
      scene.push_back({spec.entities[e].name, {p.x(), p.y(), yaw[e]}, false, spec.footprint(static_cast<int>(e))});
    }
    const vision::FrameResult fr = tracker.process(camera.render(scene, truth.t[r]), truth.t[r]);
    std::vector<Vector2d> row(spec.entities.size());
    for (const auto& s : fr.entities) {
      const int e = spec.entityIndex(s.name);
      if (e < 0) continue;
      row[static_cast<size_t>(e)] = {s.pose.x, s.pose.y};
      // A goal under a robot on it is hidden (the print is under its body): robots only.
      if (spec.entities[static_cast<size_t>(e)].kind == task::EntityKind::Robot) ++frames, unseen += !s.visible;
      max_error_m =
          std::max(max_error_m, (row[static_cast<size_t>(e)] - truth.positions[r][static_cast<size_t>(e)]).norm());
    }
    d.positions.push_back(row);
  }
  d.analyze();
  return d;
}

}  // namespace

TEST(ContactRecording, RobotsStoppingAtContactAreTrackedLearnedAndRun) {
  tasks::GeneratorOptions o;
  o.family = "task4";
  o.demos = 3;  // three segments per key: the key's own end offset is learned
  o.seed = 3;
  const task::TaskDir truth = tasks::generate(o);
  const vision::TrackerConfig config =
      vision::loadTrackerConfig(repoPath("config") + "markers.yaml", repoPath("config") + "tracker.yaml");
  auto camera_config = vision::loadSyntheticCameraConfig(repoPath("test/data/vision") + "synthetic_camera.yaml");
  camera_config.occlusions.clear();
  vision::SyntheticCamera camera(camera_config, config.markers);

  task::TaskDir recorded;
  recorded.spec = truth.spec;
  int frames = 0, unseen = 0;
  double max_error_m = 0;
  for (const auto& d : truth.demos)
    recorded.demos.push_back(recordThroughCamera(d, truth.spec, config, camera, frames, unseen, max_error_m));
  // Robots touching (4.4 cm apart, 3 cm markers) stay apart in the image: measured in
  // nearly every frame (the pose filter holds the few misses) and never off by 5 mm.
  EXPECT_LT(unseen, frames / 100) << unseen << " of " << frames;
  EXPECT_LT(max_error_m, 0.005);
  for (size_t i = 0; i < truth.demos.size(); ++i)
    ASSERT_TRUE(task::sameSteps(recorded.demos[i].steps, truth.demos[i].steps)) << i;

  // Trained on the recording: motions toward a robot end at contact.
  const gp::PrimitiveLibrary lib = gp::PrimitiveLibrary::fit(recorded);
  const task::EndPointModel& ends = lib.endPoints();
  const double contact = recorded.spec.contactDistance(0, 2);  // two Hamsters, 4.4 cm
  ASSERT_TRUE(ends.by_class.count("robot->robot"));
  EXPECT_NEAR(ends.by_class.at("robot->robot").offset.x(), -contact, 0.003);
  EXPECT_NEAR(ends.by_class.at("robot->robot").offset.y(), 0.0, 0.003);
  EXPECT_NEAR(ends.by_key.at("R1:move:R3").offset.x(), -contact, 0.003);

  // The coordinator with the learned end points: each recorded step decided again (the
  // decision the demonstration made), and the robots observed where the camera saw them
  // stop, touching their targets; their executors report DONE. It counts every motion
  // done and finishes.
  struct Counted {
    bool finished = false;
    size_t done = 0, motions = 0;
  };
  const auto coordinate = [&](const task::Demonstration& d, const task::EndPointModel& model) {
    exec::Coordinator c(recorded.spec, exec::CoordinatorConfig{}, model);
    const auto observe = [&](const std::vector<Vector2d>& p) {
      return exec::EntityObservation{p, std::vector<bool>(p.size(), true)};
    };
    c.onEntities(observe(d.positions.front()), 0.0);
    exec::CoordinatorOutput out = c.start(0.0);
    double t = 0;
    size_t step = 0;
    Counted n;
    while (out.decision && c.state() != exec::RunState::Finished) {
      t += 1;
      out = c.onDecision(out.decision->id, exec::replayDecision(d, out.decision->history), t);
      if (c.state() == exec::RunState::Finished) break;
      std::vector<exec::SegmentCommand> segments;
      for (const auto& r : out.paths) {
        const auto o = c.onPath(r.id, {{r.start, r.goal}, {0, 0}}, "", t);
        segments.insert(segments.end(), o.segments.begin(), o.segments.end());
      }
      if (step + 1 >= d.snapshots.size()) break;
      const std::vector<Vector2d>& stopped = d.snapshots[++step].positions;  // where the step ended
      out = c.onEntities(observe(stopped), t + 0.5);
      for (const auto& s : segments) {
        const auto o = c.onSegmentStatus(s.entity, s.segment_id, exec::SegmentState::Done, 1.0, "", t + 0.5);
        if (o.decision) out = o;
      }
      for (const auto& tr : c.steps().back().tokens)
        if (tr.token.isMotion()) ++n.motions, n.done += tr.state == exec::SegmentState::Done;
      if (n.done < n.motions) break;  // the run waits for the robot that has not arrived
    }
    n.finished = c.state() == exec::RunState::Finished;
    return n;
  };
  task::EndPointModel centres;  // a model whose motions end on the targets
  centres.centres = true;
  for (const auto& d : recorded.demos) {
    const Counted learned = coordinate(d, ends);
    EXPECT_TRUE(learned.finished);
    EXPECT_EQ(learned.done, learned.motions);
    EXPECT_EQ(learned.motions, 4u);  // [R1:move:R3 R2:move:R4] [R3:move:G1 R4:move:G1]
    // Told the motions end on the robots' centres, the step's placement still ends them
    // where bodies fit (task::stepEndPositions: an end inside a standing robot backs off to
    // contact), so it counts them done too: the bodies decide, not the model's format.
    const Counted centred = coordinate(d, centres);
    EXPECT_TRUE(centred.finished);
    EXPECT_EQ(centred.done, centred.motions);
  }

  // Run: each recording's steps decided again, paths from the library toward the learned
  // end points; every motion arrives within the arrival radius of its end point.
  for (const auto& gt : recorded.demos) {
    const exec::Policy replay = [&gt](const std::vector<task::Snapshot>& history) {
      exec::Decision d;
      const size_t k = history.size() - 1;
      if (k >= gt.steps.size()) d.end = true;
      else d.tokens = gt.steps[k].tokens;
      return d;
    };
    const exec::PathGenerator paths = [&lib](const task::Token& t, const Vector2d& a, const Vector2d& b) {
      return lib.generate(t, a, b).points;
    };
    exec::IdealExecution ideal;
    const exec::Trial trial = exec::runTrial(recorded.spec, gt, replay, paths, ideal, ends);
    const eval::TrialScore score = eval::scoreTrial(recorded.spec, gt, trial);
    EXPECT_TRUE(trial.ended);
    EXPECT_EQ(score.achieved_robot_motions, score.gt_robot_motions) << gt.source;
    EXPECT_TRUE(score.success);
    // A motion toward a robot ended touching it (where the target stood when the step was
    // decided: the snapshot the policy saw), not on its centre.
    for (const auto& ex : trial.executed) {
      if (!ex.token.isMotion() ||
          recorded.spec.entities[static_cast<size_t>(ex.token.target)].kind != task::EntityKind::Robot)
        continue;
      const Vector2d target =
          trial.snapshots[static_cast<size_t>(ex.step)].positions[static_cast<size_t>(ex.token.target)];
      EXPECT_NEAR((ex.executed.back() - target).norm(), contact, 0.006) << task::tokenKey(ex.token, recorded.spec);
    }
  }
}
