#include "ddace/vision/synthetic_camera.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "ddace/common/file.h"
#include "yaml_values.h"

namespace ddace::vision {

using detail::integerOr;
using detail::numberOr;
using detail::parseRoot;
using detail::stringOr;

SyntheticCameraConfig parseSyntheticCameraConfig(const std::string& text, const std::string& file) {
  YamlChecker r(file);
  SyntheticCameraConfig c;
  const YAML::Node root = parseRoot(r, text, "the synthetic camera configuration");
  r.onlyKeys(root,
             {"width", "height", "hfov_deg", "position", "look_at", "roll_deg", "table_size", "table_margin",
              "blur_sigma", "noise_sigma", "light_amplitude", "light_period", "light_gradient", "occlusions", "seed"},
             "the synthetic camera configuration");
  c.width = integerOr(r, root, "width", c.width, 64, 8192);
  c.height = integerOr(r, root, "height", c.height, 64, 8192);
  c.hfov_deg = numberOr(r, root, "hfov_deg", c.hfov_deg, 5.0, 170.0);
  auto vec = [&](const char* key, int n, std::vector<double> fallback) {
    const YAML::Node v = root[key];
    if (!v.IsDefined()) return fallback;
    if (!v.IsSequence() || static_cast<int>(v.size()) != n) {
      r.error(v, std::string("'") + key + "' must be a list of " + std::to_string(n) + " numbers");
      return fallback;
    }
    // Each element through the checker: the whole scalar, finite (a .nan camera position
    // would render nothing, silently).
    std::vector<double> out(n);
    bool ok = true;
    for (int i = 0; i < n; ++i)
      ok = r.number(v[i], std::string("'") + key + "[" + std::to_string(i) + "]'", out[i]) && ok;
    return ok ? out : fallback;
  };
  const auto pos = vec("position", 3, {c.position[0], c.position[1], c.position[2]});
  c.position = {pos[0], pos[1], pos[2]};
  const auto look = vec("look_at", 2, {c.look_at.x, c.look_at.y});
  c.look_at = {look[0], look[1]};
  const auto table = vec("table_size", 2, {c.table_size.width, c.table_size.height});
  c.table_size = {table[0], table[1]};
  c.roll_deg = numberOr(r, root, "roll_deg", c.roll_deg, -180, 180);
  c.table_margin_m = numberOr(r, root, "table_margin", c.table_margin_m, 0.0, 10.0);
  c.blur_sigma_px = numberOr(r, root, "blur_sigma", c.blur_sigma_px, 0.0, 20.0);
  c.noise_sigma = numberOr(r, root, "noise_sigma", c.noise_sigma, 0.0, 100.0);
  c.light_amplitude = numberOr(r, root, "light_amplitude", c.light_amplitude, 0.0, 0.9);
  c.light_period_s = numberOr(r, root, "light_period", c.light_period_s, 0.01, 1e6);
  c.light_gradient = numberOr(r, root, "light_gradient", c.light_gradient, 0.0, 0.9);
  c.seed = static_cast<unsigned>(integerOr(r, root, "seed", static_cast<int>(c.seed), 0));
  const YAML::Node occ = root["occlusions"];
  if (occ.IsDefined() && !occ.IsNull()) {
    if (!occ.IsSequence()) {
      r.error(occ, "'occlusions' must be a list of {entity, start, duration}");
    } else {
      for (const auto& o : occ) {
        if (!r.expectMap(o, "an occlusion")) continue;
        r.onlyKeys(o, {"entity", "start", "duration"}, "an occlusion");
        Occlusion oc;
        oc.entity = stringOr(r, o, "entity", "");
        if (oc.entity.empty()) r.error(o, "an occlusion needs 'entity'");
        oc.start_s = numberOr(r, o, "start", 0.0, 0.0, 1e9);
        oc.end_s = oc.start_s + numberOr(r, o, "duration", 0.5, 0.0, 1e9);
        c.occlusions.push_back(oc);
      }
    }
  }
  r.throwIfErrors();
  return c;
}

SyntheticCameraConfig loadSyntheticCameraConfig(const std::string& path) {
  return parseSyntheticCameraConfig(readTextFile(path), path);
}

SyntheticCamera::SyntheticCamera(SyntheticCameraConfig config, MarkerConfig markers)
    : config_(std::move(config)), markers_(std::move(markers)), rng_(config_.seed) {
  family_.backend = markers_.backend;
  family_.family = markers_.family;
  const double w = config_.width, h = config_.height;
  const double f = (w / 2) / std::tan(config_.hfov_deg * M_PI / 360.0);
  K_ = cv::Matx33d(f, 0, (w - 1) / 2, 0, f, (h - 1) / 2, 0, 0, 1);

  const cv::Vec3d C = config_.position;
  cv::Vec3d z = cv::Vec3d(config_.look_at.x, config_.look_at.y, 0.0) - C;
  if (C[2] <= 0 || z[2] >= 0) throw Error("synthetic camera: the camera must be above the table looking down");
  z = cv::normalize(z);
  const cv::Vec3d ex(1, 0, 0);
  cv::Vec3d x = ex - z * ex.dot(z);
  if (cv::norm(x) < 1e-6) x = cv::Vec3d(0, -1, 0) - z * cv::Vec3d(0, -1, 0).dot(z);
  x = cv::normalize(x);
  cv::Vec3d y = z.cross(x);
  const double roll = config_.roll_deg * M_PI / 180.0;
  const cv::Vec3d xr = x * std::cos(roll) + y * std::sin(roll);
  const cv::Vec3d yr = z.cross(xr);
  R_ = cv::Matx33d(xr[0], xr[1], xr[2], yr[0], yr[1], yr[2], z[0], z[1], z[2]);
  t_ = -(R_ * C);

  background_ = cv::Mat(config_.height, config_.width, CV_8UC1, cv::Scalar(70));
  const double x0 = config_.table_origin.x, y0 = config_.table_origin.y;
  const double x1 = x0 + config_.table_size.width, y1 = y0 + config_.table_size.height;
  const double mg = config_.table_margin_m;
  drawConvex(background_, {{x0 - mg, y0 - mg, 0}, {x1 + mg, y0 - mg, 0}, {x1 + mg, y1 + mg, 0}, {x0 - mg, y1 + mg, 0}},
             215);
  // Some clutter on the table: darker blotches (wood grain, stains) that are not markers.
  cv::RNG clutter(config_.seed + 17);
  for (int i = 0; i < 25; ++i) {
    const cv::Point2d p = project({clutter.uniform(x0, x1), clutter.uniform(y0, y1), 0});
    cv::circle(background_, p, clutter.uniform(3, 14), cv::Scalar(clutter.uniform(150, 200)), cv::FILLED, cv::LINE_AA);
  }
  for (const auto& c : markers_.corners)
    drawMarker(background_, c.id, markers_.corner_size_m, {c.table_xy.x, c.table_xy.y, 0.0}, 0.0, MarkerPart::Whole);

  light_ = cv::Mat(config_.height, config_.width, CV_32F);
  for (int r = 0; r < config_.height; ++r)
    for (int c = 0; c < config_.width; ++c)
      light_.at<float>(r, c) = static_cast<float>(1.0 - config_.light_gradient * c / w);
}

SyntheticCameraConfig framedOnCorners(SyntheticCameraConfig c, const MarkerConfig& markers) {
  if (markers.corners.empty()) return c;
  cv::Point2d lo(INFINITY, INFINITY), hi(-INFINITY, -INFINITY);
  for (const auto& k : markers.corners) {
    lo = {std::min(lo.x, k.table_xy.x), std::min(lo.y, k.table_xy.y)};
    hi = {std::max(hi.x, k.table_xy.x), std::max(hi.y, k.table_xy.y)};
  }
  const cv::Size2d size(hi.x - lo.x, hi.y - lo.y);
  if (!(size.width > 0 && size.height > 0)) return c;
  const double s = std::max(size.width / c.table_size.width, size.height / c.table_size.height);
  const cv::Point2d from = c.table_origin + cv::Point2d(c.table_size.width, c.table_size.height) / 2;
  const cv::Point2d to = (lo + hi) / 2;
  c.position = {to.x + s * (c.position[0] - from.x), to.y + s * (c.position[1] - from.y), s * c.position[2]};
  c.look_at = to + s * (c.look_at - from);
  c.table_origin = lo;
  c.table_size = size;
  return c;
}

cv::Point2d SyntheticCamera::project(const cv::Vec3d& X) const {
  const cv::Vec3d p = K_ * (R_ * X + t_);
  return {p[0] / p[2], p[1] / p[2]};
}

CameraModel SyntheticCamera::camera() const {
  CameraModel m;
  m.K = K_;
  m.valid = true;
  return m;
}

TableFrame SyntheticCamera::tableFrame() const {
  return TableFrame::fromCameraPose(K_, R_, t_);
}

bool SyntheticCamera::occluded(const std::string& entity, double t_s) const {
  for (const auto& o : config_.occlusions)
    if (o.entity == entity && t_s >= o.start_s && t_s < o.end_s) return true;
  return false;
}

void SyntheticCamera::drawConvex(cv::Mat& img, const std::vector<cv::Vec3d>& corners, int grey) {
  std::vector<cv::Point> pts;
  for (const auto& c : corners) {
    const cv::Point2d p = project(c);
    pts.emplace_back(cvRound(p.x * 16), cvRound(p.y * 16));
  }
  cv::fillConvexPoly(img, pts, cv::Scalar(grey), cv::LINE_AA, 4);
}

void SyntheticCamera::drawMarker(cv::Mat& img, int id, double size_m, const PlanarPose& pose, double height_m,
                                 MarkerPart part) {
  MarkerImage m = renderMarker(family_, id);
  if (part == MarkerPart::QuietZone) {
    m.cells.setTo(255);
  } else if (part == MarkerPart::Square) {
    // Only the printed cells inside the white margin (the black square; for AprilTag's
    // reversed-border families also the data ring around it), centred like the whole.
    cv::Mat dark = m.cells < 128;
    const cv::Rect ink = cv::boundingRect(dark);
    const int pad = std::min(ink.x, m.cells.cols - ink.x - ink.width);
    m.cells = m.cells(cv::Rect(pad, pad, m.cells.cols - 2 * pad, m.cells.rows - 2 * pad)).clone();
  }
  // Supersample the cells so that the warp interpolates edges, not cells.
  constexpr int kScale = 12;
  cv::Mat big;
  cv::resize(m.cells, big, cv::Size(), kScale, kScale, cv::INTER_NEAREST);
  const double cell_m = size_m / m.square_cells;
  const double half = m.cells.cols * cell_m / 2;  // quiet zone included
  const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
  // Printed top-left, top-right, bottom-right, bottom-left; printed "up" is table +y at yaw 0.
  const double local[4][2] = {{-half, half}, {half, half}, {half, -half}, {-half, -half}};
  std::vector<cv::Point2f> dst, src;
  const float n = static_cast<float>(big.cols);
  const cv::Point2f src_pts[4] = {{-0.5f, -0.5f}, {n - 0.5f, -0.5f}, {n - 0.5f, n - 0.5f}, {-0.5f, n - 0.5f}};
  for (int k = 0; k < 4; ++k) {
    const double x = pose.x + c * local[k][0] - s * local[k][1];
    const double y = pose.y + s * local[k][0] + c * local[k][1];
    const cv::Point2d p = project({x, y, height_m});
    dst.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
    src.push_back(src_pts[k]);
  }
  cv::Rect box = cv::boundingRect(dst);
  box = cv::Rect(box.x - 2, box.y - 2, box.width + 4, box.height + 4) & cv::Rect(0, 0, img.cols, img.rows);
  if (box.empty()) return;
  for (auto& p : dst) p -= cv::Point2f(static_cast<float>(box.x), static_cast<float>(box.y));
  const cv::Mat H = cv::getPerspectiveTransform(src, dst);
  cv::Mat patch, mask;
  cv::warpPerspective(big, patch, H, box.size(), cv::INTER_AREA, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::warpPerspective(cv::Mat(big.size(), CV_8UC1, cv::Scalar(255)), mask, H, box.size(), cv::INTER_AREA,
                      cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat roi = img(box);
  for (int r = 0; r < roi.rows; ++r)
    for (int col = 0; col < roi.cols; ++col) {
      const int a = mask.at<uint8_t>(r, col);
      if (a == 0) continue;
      uint8_t& out = roi.at<uint8_t>(r, col);
      // patch is premultiplied by the mask (both warped with a black border).
      out = cv::saturate_cast<uint8_t>(patch.at<uint8_t>(r, col) + out * (255 - a) / 255.0);
    }
}

cv::Mat SyntheticCamera::render(const std::vector<TrueEntity>& entities, double t_s) {
  cv::Mat img = background_.clone();
  auto markerOf = [&](const TrueEntity& te) -> const EntityMarker* {
    for (const auto& e : markers_.entities)
      if (e.name == te.name) return &e;
    return nullptr;
  };
  std::vector<std::pair<const EntityMarker*, PlanarPose>> prints, raised;  // goals / on a body
  for (const auto& te : entities)
    if (const EntityMarker* em = markerOf(te)) {
      PlanarPose marker_pose = te.pose;
      marker_pose.yaw = te.pose.yaw - em->yaw_offset_rad;
      (em->kind == task::EntityKind::Goal ? prints : raised).emplace_back(em, marker_pose);
    }
  std::stable_sort(prints.begin(), prints.end(),
                   [](const auto& a, const auto& b) { return a.first->height_m < b.first->height_m; });
  std::stable_sort(raised.begin(), raised.end(),
                   [](const auto& a, const auto& b) { return a.first->height_m < b.first->height_m; });
  // White margins of a layer's markers first, then their black squares over them: two
  // markers closer than their margins still show both squares (as prints would).
  auto drawLayer = [&](const std::vector<std::pair<const EntityMarker*, PlanarPose>>& layer) {
    for (const auto& [em, pose] : layer) drawMarker(img, em->id, em->size_m, pose, em->height_m, MarkerPart::QuietZone);
    for (const auto& [em, pose] : layer) drawMarker(img, em->id, em->size_m, pose, em->height_m, MarkerPart::Square);
  };
  // In the order things stack: prints lying on the table (goals), the bodies standing on
  // it (a robot parked on a goal covers the goal's print), the markers on the bodies.
  // Bodies are the task's footprints, so bodies that keep apart in a simulation are drawn
  // apart, and robots stopped at contact touch; markers stay on top of overlapping ones.
  drawLayer(prints);
  for (const auto& te : entities) {
    const EntityMarker* em = markerOf(te);
    if (!em) continue;
    const task::Footprint body = te.footprint ? *te.footprint : task::footprint(task::Entity{te.name, em->kind, ""});
    if (!body.obstacle) continue;
    constexpr int kRim = 48;  // polygon corners of a disc: smooth at a few pixels per cm
    std::vector<cv::Vec3d> rim;
    for (int k = 0; k < kRim; ++k) {
      const double a = 2 * M_PI * k / kRim;
      rim.emplace_back(te.pose.x + body.radius_m * std::cos(a), te.pose.y + body.radius_m * std::sin(a), 0.0);
    }
    drawConvex(img, rim, em->kind == task::EntityKind::Robot ? 45 : 120);
  }
  drawLayer(raised);
  for (const auto& te : entities) {
    if (!te.occluded && !occluded(te.name, t_s)) continue;
    // A hand: a blob over the marker with a shadow beside it.
    const cv::Point2d p = project({te.pose.x, te.pose.y, 0.08});
    const cv::Point2d q = project({te.pose.x + 0.05, te.pose.y, 0.08});
    const double r = cv::norm(q - p);
    cv::ellipse(img, p + cv::Point2d(0.3 * r, 0.3 * r), cv::Size2d(1.4 * r, 1.0 * r), 30, 0, 360, cv::Scalar(60),
                cv::FILLED, cv::LINE_AA);
    cv::ellipse(img, p, cv::Size2d(1.4 * r, 1.0 * r), 30, 0, 360, cv::Scalar(165), cv::FILLED, cv::LINE_AA);
  }
  if (config_.blur_sigma_px > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), config_.blur_sigma_px);
  const double gain = 1.0 + config_.light_amplitude * std::sin(2 * M_PI * t_s / config_.light_period_s);
  cv::Mat f;
  img.convertTo(f, CV_32F, gain);
  f = f.mul(light_);
  if (config_.noise_sigma > 0) {
    cv::Mat noise(f.size(), CV_32F);
    rng_.fill(noise, cv::RNG::NORMAL, 0.0, config_.noise_sigma);
    f += noise;
  }
  f.convertTo(img, CV_8U);
  return img;
}

}  // namespace ddace::vision
