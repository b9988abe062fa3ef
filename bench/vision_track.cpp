// The overhead tracker against OpenCV's own full-frame aruco detector, in one run, on
// the tracker's three 1280x720 scenes (ddace/vision/tracker_scenes.h): "small" (12
// robots with 3 cm markers), "fast" (+ a ball at 0.8 m/s) and "edge" (robots along the
// table's edges under a 40 % radial light falloff, one starting in the darkest corner).
// Both backends; for tag36h11 both engines that read it (OpenCV's DICT_APRILTAG_36h11
// and libapriltag), each in its own tracker on the same frames. The reference is
// OpenCV's detector with its default parameters on the whole frame (for AprilTag its
// DICT_APRILTAG_36h11, which reads the same prints). Writes docs/bench/vision_track.md.
//
// Usage: bench_vision_track [--frames N] [--out FILE]
// Timings are CPU time of the one thread that runs everything (OpenCV single-threaded,
// AprilTag nthreads = 1), so a loaded machine does not skew them, reported as ratios
// against the reference measured on the same frames. "Lost": markers the
// reference found in a frame and the tracker did not (the goal is 0). Per entity: the
// fraction of frames in which the reference found it and the fraction of those in
// which the tracker reported it visible (the goal is >= 99 %).
#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ddace/common/clock.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/machine.h"
#include "ddace/vision/tracker.h"
#include "ddace/vision/tracker_scenes.h"
#include "results.h"

using namespace ddace::vision;

namespace {

/// One tracker configuration measured on a scene.
struct Variant {
  std::string name;  ///< "aruco", "apriltag (opencv)", ...
  TrackerConfig config;
  int off_table = 0;  ///< robots configured in markers.yaml but never on the table
};

struct EntityCount {
  long reference = 0;     // frames in which the reference found its marker
  long visible = 0;       // frames in which the tracker reported it visible
  long both = 0;          // ... among the reference's frames
  long longest_miss = 0;  // longest run of the reference's frames without it, frames
  long run = 0;
};

struct Result {
  double tracker_ms = 0, full_ms = 0;
  long lost = 0, roi_frames = 0, second_looks = 0, first_look_misses = 0;
  long absent_frames = 0, absent_candidates = 0;  // frames with an absent-marker search, regions read
  std::vector<double> errors_m;                   // visible entities vs the truth
  double robot_side_px = 0;                       // mean edge of the robots' markers in the image
  long robot_sides = 0;
  std::vector<EntityCount> entities;
};

struct SceneRun {
  double reference_ms = 0;
  long reference_found = 0, frames = 0;
  std::vector<std::string> names;
  std::vector<long> reference_entity;      // frames in which the reference found each entity
  std::vector<double> reference_errors_m;  // the reference's positions vs the truth
  std::vector<Result> variants;
};

/// The trackers of `variants` on `renderer`'s scene (their markers.yaml with the robots off
/// the table added), each with its detector on the whole frame too.
struct Trackers {
  std::vector<std::unique_ptr<Tracker>> trackers;
  std::vector<std::unique_ptr<FiducialDetector>> full;
};

Trackers makeTrackers(const TrackerSceneRenderer& renderer, const std::vector<Variant>& variants) {
  const MarkerConfig& markers = renderer.markers();
  Trackers t;
  for (const auto& v : variants) {
    TrackerConfig tc = v.config;
    tc.markers = markers;
    for (int i = 0; i < v.off_table; ++i) {  // ids the scenes do not use
      EntityMarker absent = markers.entities.front();
      absent.id = 40 + i;
      absent.name = "absent" + std::to_string(i + 1);
      tc.markers.entities.push_back(absent);
    }
    t.trackers.push_back(std::make_unique<Tracker>(tc));
    t.trackers.back()->setCamera(renderer.camera());
    t.full.push_back(makeDetector(t.trackers.back()->config().detector));
  }
  return t;
}

/// The reference on one frame: its time and accuracy into `res`; the scene's markers it found.
std::set<int> referenceFrame(const cv::Mat& img, const std::vector<TrueEntity>& truth, DetectorBackend backend,
                             const MarkerConfig& markers, const TableFrame& table, SceneRun& res) {
  const double t0 = ddace::threadCpuS();
  const std::vector<Detection> ref_found = referenceDetect(img, backend);
  res.reference_ms += 1000 * (ddace::threadCpuS() - t0);
  std::set<int> reference;
  for (const Detection& d : ref_found) {
    if (markers.isCorner(d.id) || markers.entityById(d.id)) reference.insert(d.id);
    // The reference's own accuracy: its corners, the true table frame.
    for (size_t i = 0; i < markers.entities.size(); ++i)
      if (markers.entities[i].id == d.id) {
        const PlanarPose p = table.markerPose(d, markers.entities[i].height_m);
        res.reference_errors_m.push_back(std::hypot(p.x - truth[i].pose.x, p.y - truth[i].pose.y));
      }
  }
  res.reference_found += static_cast<long>(reference.size());
  for (size_t i = 0; i < markers.entities.size(); ++i)
    res.reference_entity[i] += reference.count(markers.entities[i].id) > 0;
  return reference;
}

/// One tracker (and its detector on the whole frame) on one frame, counted into `r`
/// against what the reference found there.
void trackFrame(const cv::Mat& img, double t, const std::vector<TrueEntity>& truth, const std::set<int>& reference,
                const MarkerConfig& markers, Tracker& tracker, FiducialDetector& full, Result& r) {
  double t0 = ddace::threadCpuS();
  full.detect(img);
  r.full_ms += 1000 * (ddace::threadCpuS() - t0);
  t0 = ddace::threadCpuS();
  const FrameResult fr = tracker.process(img, t);
  r.tracker_ms += 1000 * (ddace::threadCpuS() - t0);
  r.roi_frames += !fr.full_frame;
  r.second_looks += fr.second_look;
  r.first_look_misses += fr.first_look_misses;
  r.absent_frames += fr.absent > 0;
  r.absent_candidates += fr.absent_candidates;
  std::set<int> found;
  for (const auto& d : fr.detections) {
    found.insert(d.id);
    if (markers.entityById(d.id) && markers.entityById(d.id)->kind == ddace::task::EntityKind::Robot) {
      r.robot_side_px += d.sidePx();
      ++r.robot_sides;
    }
  }
  for (const int id : reference) r.lost += !found.count(id);
  for (size_t i = 0; i < r.entities.size(); ++i) {  // the scene's entities (not those off the table)
    EntityCount& c = r.entities[i];
    const bool ref = reference.count(markers.entities[i].id) > 0, vis = fr.entities[i].visible;
    c.reference += ref;
    c.visible += vis;
    c.both += ref && vis;
    c.run = ref && !vis ? c.run + 1 : 0;
    c.longest_miss = std::max(c.longest_miss, c.run);
    if (vis)
      r.errors_m.push_back(
          std::hypot(fr.entities[i].pose.x - truth[i].pose.x, fr.entities[i].pose.y - truth[i].pose.y));
  }
}

SceneRun run(TrackerScene scene, DetectorBackend backend, const std::vector<Variant>& variants, int frames) {
  TrackerSceneRenderer renderer(scene, backend);
  const MarkerConfig& markers = renderer.markers();
  Trackers t = makeTrackers(renderer, variants);
  SceneRun res;
  res.variants.resize(variants.size());
  for (Result& r : res.variants) r.entities.resize(markers.entities.size());
  for (const auto& e : markers.entities) res.names.push_back(e.name);
  res.reference_entity.assign(markers.entities.size(), 0);
  // Warm up (first calls allocate, caches fill): not timed.
  {
    const cv::Mat img = renderer.render(renderer.truth(0.0), 0.0);
    for (int i = 0; i < 3; ++i) {
      referenceDetect(img, backend);
      for (auto& d : t.full) d->detect(img);
    }
  }
  const TableFrame table = renderer.tableFrame();
  for (int f = 0; f < frames; ++f) {
    const double time = f / 30.0;
    const auto truth = renderer.truth(time);
    const cv::Mat img = renderer.render(truth, time);
    const std::set<int> reference = referenceFrame(img, truth, backend, markers, table, res);
    for (size_t v = 0; v < variants.size(); ++v)
      trackFrame(img, time, truth, reference, markers, *t.trackers[v], *t.full[v], res.variants[v]);
    ++res.frames;
  }
  return res;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

double percent(long part, long whole) {
  return whole > 0 ? 100.0 * static_cast<double>(part) / whole : 100.0;
}

/// Smallest fraction of the reference's frames in which an entity was visible (%), and which.
std::pair<double, std::string> worstEntity(const SceneRun& s, const Result& r) {
  std::pair<double, std::string> worst{100.0, "-"};
  for (size_t i = 0; i < r.entities.size(); ++i) {
    const double p = percent(r.entities[i].both, r.entities[i].reference);
    if (p < worst.first) worst = {p, s.names[i]};
  }
  return worst;
}

/// The command line: frames per scene and backend, and where the results go ("" = the
/// repository's docs/bench/vision_track.md); nothing when it is not understood (said why).
struct Options {
  int frames = 300;
  std::string out;
};

std::optional<Options> parseOptions(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc) o.frames = std::atoi(argv[++i]);
    else if (a == "--out" && i + 1 < argc) o.out = argv[++i];
    else {
      std::cerr << "usage: bench_vision_track [--repo DIR] [--frames N] [--out FILE]\n";
      return std::nullopt;
    }
  }
  if (o.frames < 1) {
    std::cerr << "bench_vision_track: --frames must be >= 1\n";
    return std::nullopt;
  }
  return o;
}

/// Keep freed memory in the heap: otherwise glibc returns the renderer's large buffers to
/// the kernel and whatever runs first after a render (the reference) pays ~2000 page
/// faults per frame for its own images, doubling its time. A tracker node reuses its
/// memory frame after frame; so do the measured calls here.
void keepFreedMemory() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

/// The trackers measured with `backend`: the shipped tuning, for AprilTag with both
/// engines that read tag36h11 (the shipped one first), and with 2 robots off the table.
std::vector<Variant> variantsFor(DetectorBackend backend, const TrackerConfig& tuning) {
  std::vector<Variant> variants;
  if (backend == DetectorBackend::Aruco) {
    variants.push_back({"aruco", tuning});
    variants.push_back({"aruco, 2 robots off the table", tuning, 2});
    return variants;
  }
  for (const AprilTagEngine engine : {tuning.detector.apriltag_engine, otherEngine(tuning.detector.apriltag_engine)}) {
    Variant v{"apriltag (" + toString(engine) + ")", tuning};
    v.config.detector.apriltag_engine = engine;
    variants.push_back(v);
  }
  variants.push_back(
      {"apriltag (" + toString(tuning.detector.apriltag_engine) + "), 2 robots off the table", tuning, 2});
  return variants;
}

const char* const kSummaryHeader =
    "| scene | backend | reference (ms) | backend, full frame (ms) | tracker (ms) | tracker / reference | "
    "region frames | first-look misses | second looks | absent searches (candidates) | found by reference | "
    "lost | worst entity: visible in the reference's frames | position p95 / max (mm) | reference: position p95 / "
    "max (mm) | robot marker edge (px) |\n"
    "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";

/// The summary table's row of one tracker on one scene.
std::string summaryRow(TrackerScene scene, const std::string& variant, const SceneRun& s, const Result& r) {
  const auto worst = worstEntity(s, r);
  return ddace::bench::formatted(
      "| %s | %s | %.2f | %.2f | %.2f | %.2f | %ld / %ld | %ld | %ld | %ld (%ld) | %ld | %ld | %.1f %% (%s) | %.2f / "
      "%.2f | %.2f / %.2f | %.1f |\n",
      toString(scene).c_str(), variant.c_str(), s.reference_ms / s.frames, r.full_ms / s.frames,
      r.tracker_ms / s.frames, r.tracker_ms / s.reference_ms, r.roi_frames, s.frames, r.first_look_misses,
      r.second_looks, r.absent_frames, r.absent_candidates, s.reference_found, r.lost, worst.first,
      worst.second.c_str(), percentile(r.errors_m, 0.95) * 1000, percentile(r.errors_m, 1.0) * 1000,
      percentile(s.reference_errors_m, 0.95) * 1000, percentile(s.reference_errors_m, 1.0) * 1000,
      r.robot_side_px / std::max(1L, r.robot_sides));
}

/// A column of the per-entity table: a tracker's name, its scene run and its variant there.
struct Column {
  std::string name;
  size_t run = 0, variant = 0;
};

/// Per entity: reference % of frames | tracker % of frames, % of the reference's frames
/// (longest miss), one column pair per tracker.
std::string entityTable(TrackerScene scene, const std::vector<SceneRun>& runs, const std::vector<Column>& columns) {
  std::ostringstream details;
  details << "\n**" << toString(scene) << "**: per entity, the percentage of frames in which the reference found "
          << "its marker; the percentage of frames in which the tracker reported it visible, and of the "
             "reference's frames (longest run of the reference's frames without it, in frames).\n\n| entity |";
  for (const auto& column : columns) details << " " << column.name << ": reference | tracker |";
  details << "\n|---|";
  for (size_t i = 0; i < columns.size(); ++i) details << "---|---|";
  details << "\n";
  for (size_t e = 0; e < runs.front().names.size(); ++e) {
    details << "| " << runs.front().names[e] << " |";
    for (const auto& column : columns) {
      const SceneRun& s = runs[column.run];
      const EntityCount& c = s.variants[column.variant].entities[e];
      details << ddace::bench::formatted(" %.1f | %.1f, %.1f (%ld) |", percent(s.reference_entity[e], s.frames),
                                         percent(c.visible, s.frames), percent(c.both, c.reference), c.longest_miss);
    }
    details << "\n";
  }
  return details.str();
}

/// One scene with both backends: the summary's rows (also printed as they come), the
/// per-entity table, and whether the reference found anything in every run.
struct SceneTables {
  std::string rows, entities;
  bool reference_found = true;
};

SceneTables measureScene(TrackerScene scene, const TrackerConfig& tuning, int frames) {
  SceneTables t;
  std::vector<SceneRun> runs;  // one per backend
  std::vector<Column> columns;
  for (const DetectorBackend backend : {DetectorBackend::Aruco, DetectorBackend::AprilTag}) {
    const std::vector<Variant> variants = variantsFor(backend, tuning);
    runs.push_back(run(scene, backend, variants, frames));
    const SceneRun& s = runs.back();
    t.reference_found = t.reference_found && s.reference_found > 0;
    for (size_t v = 0; v < variants.size(); ++v) {
      const std::string row = summaryRow(scene, variants[v].name, s, s.variants[v]);
      t.rows += row;
      std::cout << row << std::flush;
      columns.push_back({variants[v].name, runs.size() - 1, v});
    }
  }
  t.entities = entityTable(scene, runs, columns);
  return t;
}

/// docs/bench/vision_track.md.
std::string report(int frames, const std::string& summary, const std::string& details) {
  std::ostringstream md;
  md << "# The overhead tracker against OpenCV (bench_vision_track)\n\n"
     << "1280x720 frames of the synthetic overhead camera (tilted 9 degrees, rolled 3, blur, noise), " << frames
     << " frames at 30 frames/s per scene and backend, CPU time of one thread, the tuning of config/tracker.yaml, "
        "intrinsics given. "
        "Scenes (`ddace/vision/tracker_scenes.h`): *small*: 4 corner markers and 12 robots with 3 cm markers on slow "
        "circles, 40 % light gradient across the image; *fast*: the same and a 3 cm ball passed across the table at "
        "0.8 m/s; *edge*: 4 corner markers and 11 robots along the table's edges, near the image's borders, under a "
        "40 % radial light falloff toward the image's corners, R1 parked in the darkest corner for a second, then "
        "driving to the middle and back at 0.1 m/s. *Reference*: OpenCV 4.6 `cv::aruco::detectMarkers` with its "
        "default parameters on the whole frame (for AprilTag: its `DICT_APRILTAG_36h11`, the same prints). *Lost*: "
        "markers the reference found in a frame and the tracker did not. *Time ratio*: the tracker's mean time per "
        "frame (detection, table frame, poses, filtering; full-frame passes included) over the reference's, measured "
        "on the same frames. *Backend, full frame*: the tracker's detector (shipped tuning, corner refinement) on the "
        "whole frame. *apriltag (opencv)* and *apriltag (libapriltag)*: the tracker with each engine that reads "
        "tag36h11 (`apriltag.engine`), on the same frames. *First-look misses*: markers not found in their "
        "first-look region (predicted box, one threshold window matched to the marker) and searched again at once "
        "in their wide region with every window. *Second looks*: frames in which a marker was still missing and was "
        "searched for again with the second-look detector (AprilTag: libapriltag at full resolution). *Absent "
        "searches*: frames in which a configured marker that the regions do not follow (never seen, or unseen for "
        "longer than the hold) was searched for over the rest of the image, and in brackets the regions of "
        "marker-sized quadrilaterals read for it; *2 robots off the table*: the same tracker with two more robots "
        "in markers.yaml that are never on the table (searched for in every frame). Position errors: "
        "entities the tracker "
        "reports visible, against the true poses; the reference's: the centres of its detections mapped through "
        "the true table frame (with the markers' heights).\n\n"
     << kSummaryHeader << summary << details
     << "\nGoals: no marker lost that the reference finds; every entity visible in at least 99 % of the "
        "frames in which the reference finds it; aruco at most 0.5x and AprilTag at most 1.0x the reference's time "
        "per frame.\n\n"
     << "Written by `bench_vision_track` (`ddace bench vision_track`), " << ddace::utcNow() << ", load average "
     << ddace::loadAverage() << " while it ran.\n";
  return md.str();
}

}  // namespace

int main(int argc, char** argv) try {
  const std::filesystem::path repo = ddace::bench::repositoryFromArgs(argc, argv, {"config/tracker.yaml"});
  const std::optional<Options> options = parseOptions(argc, argv);
  if (!options) return 2;
  cv::setNumThreads(1);
  keepFreedMemory();
  TrackerConfig tuning;
  const std::string tuning_file = (repo / "config" / "tracker.yaml").string();
  parseTrackerTuning(ddace::readTextFile(tuning_file), tuning_file, tuning);
  std::string summary, details;
  bool ok = true;
  for (const TrackerScene scene : {TrackerScene::Small, TrackerScene::Fast, TrackerScene::Edge}) {
    const SceneTables t = measureScene(scene, tuning, options->frames);
    summary += t.rows;
    details += t.entities;
    ok = ok && t.reference_found;
  }
  const std::string md = report(options->frames, summary, details);
  if (options->out.empty()) {
    ddace::bench::writeResults(repo, "vision_track", md);
  } else {
    ddace::writeTextFile(options->out, md);
    std::cout << "wrote " << options->out << "\n";
  }
  return ok ? 0 : 1;
} catch (const std::exception& e) {
  std::cerr << "bench_vision_track: error: " << e.what() << "\n";
  return 1;
}
