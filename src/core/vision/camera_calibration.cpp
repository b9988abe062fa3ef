#include "ddace/vision/camera_calibration.h"

#include <cmath>

#include "ddace/common/file.h"
#include "yaml_values.h"

namespace ddace::vision {

using detail::integerOr;
using detail::parseRoot;
using detail::stringOr;

namespace {

// `{rows, cols, data}` with the expected shape; false (errors recorded) otherwise.
bool readMatrix(YamlChecker& c, const YAML::Node& root, const std::string& key, int rows, int cols,
                std::vector<double>& out, bool cols_free = false) {
  const YAML::Node m = root[key];
  if (!m.IsDefined()) return false;
  if (!c.expectMap(m, "'" + key + "'")) return false;
  c.onlyKeys(m, {"rows", "cols", "data"}, "'" + key + "'");
  const int r = integerOr(c, m, "rows", -1, 1, 100), k = integerOr(c, m, "cols", -1, 1, 100);
  bool ok = true;
  if (!m["rows"] || !m["cols"] || !m["data"]) {
    c.error(m, "'" + key + "' needs rows, cols and data");
    return false;
  }
  if (r != rows || (!cols_free && k != cols)) {
    c.error(m, "'" + key + "' must be " + std::to_string(rows) + " x " + (cols_free ? "n" : std::to_string(cols)) +
                   " (got " + std::to_string(r) + " x " + std::to_string(k) + ")");
    ok = false;
  }
  const YAML::Node data = m["data"];
  if (!data.IsSequence()) {
    c.error(data, "'" + key + ".data' must be a list of numbers");
    return false;
  }
  if (ok && data.size() != static_cast<size_t>(r * k)) {
    c.error(data, "'" + key + ".data' has " + std::to_string(data.size()) +
                      " numbers, rows x cols = " + std::to_string(r * k));
    ok = false;
  }
  out.clear();
  for (const auto& v : data) {
    double x = 0;
    if (c.number(v, "'" + key + "' entry", x)) out.push_back(x);
    else ok = false;
  }
  return ok;
}

}  // namespace

CameraCalibration parseCameraCalibration(const std::string& text, const std::string& file) {
  YamlChecker c(file);
  const YAML::Node root = parseRoot(c, text, "a camera calibration (camera_info YAML)");
  c.onlyKeys(root,
             {"image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
              "distortion_coefficients", "rectification_matrix", "projection_matrix"},
             "the camera calibration");
  CameraCalibration cal;
  for (const char* key :
       {"image_width", "image_height", "camera_matrix", "distortion_model", "distortion_coefficients"})
    c.required(root, key);
  cal.camera.image_size.width = integerOr(c, root, "image_width", 0, 1, 100000);
  cal.camera.image_size.height = integerOr(c, root, "image_height", 0, 1, 100000);
  cal.camera_name = stringOr(c, root, "camera_name", "");
  std::vector<double> k;
  if (readMatrix(c, root, "camera_matrix", 3, 3, k)) {
    cal.camera.K = cv::Matx33d(k.data());
    if (!(k[0] > 0 && k[4] > 0) || k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1)
      c.error(root["camera_matrix"]["data"],
              "'camera_matrix' must be [fx 0 cx 0 fy cy 0 0 1] with fx, fy > 0 (a pinhole camera matrix)");
  }
  cal.distortion_model = stringOr(c, root, "distortion_model", "");
  size_t expected = 0;
  if (cal.distortion_model == "plumb_bob") {
    expected = 5;
  } else if (cal.distortion_model == "rational_polynomial") {
    expected = 8;
  } else if (root["distortion_model"]) {
    c.error(root["distortion_model"], "distortion_model '" + cal.distortion_model +
                                          "' is not supported (plumb_bob or rational_polynomial; recalibrate "
                                          "without the fisheye model)");
  }
  std::vector<double> d;
  if (readMatrix(c, root, "distortion_coefficients", 1, 0, d, true) && expected && d.size() != expected)
    c.error(root["distortion_coefficients"], "distortion_model " + cal.distortion_model + " needs " +
                                                 std::to_string(expected) + " coefficients (got " +
                                                 std::to_string(d.size()) + ")");
  cal.camera.D = d;
  std::vector<double> unused;
  readMatrix(c, root, "rectification_matrix", 3, 3, unused);
  readMatrix(c, root, "projection_matrix", 3, 4, unused);
  c.throwIfErrors();
  cal.camera.valid = true;
  return cal;
}

CameraCalibration loadCameraCalibration(const std::string& path) {
  return parseCameraCalibration(readTextFile(path), path);
}

}  // namespace ddace::vision
