// libFuzzer target: config/tracker.yaml (detector, region-of-interest and filter tuning)
// is accepted or refused with a ddace::Error, never a crash or another exception. The
// markers are the shipped config/markers.yaml.
// fuzz-modules: vision task
// fuzz-max-len: 16384
#include <cstdint>
#include <string>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/vision/tracker.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const ddace::vision::MarkerConfig markers = ddace::vision::parseMarkerConfig(
      ddace::readTextFile((ddace::findRepository("", {"config/markers.yaml"}) / "config/markers.yaml").string()),
      "markers.yaml");
  ddace::vision::TrackerConfig config;
  config.markers = markers;
  try {
    ddace::vision::parseTrackerTuning(std::string(reinterpret_cast<const char*>(data), size), "tracker.yaml", config);
  } catch (const ddace::Error&) {
  }
  return 0;
}
