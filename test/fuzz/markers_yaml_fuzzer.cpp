// libFuzzer target: config/markers.yaml (fiducial ids, entity names, table corners) is
// accepted or refused with a ddace::Error, never a crash or another exception.
// fuzz-modules: vision task
// fuzz-max-len: 16384
#include <cstdint>
#include <string>

#include "ddace/common/error.h"
#include "ddace/vision/tracker.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    ddace::vision::parseMarkerConfig(std::string(reinterpret_cast<const char*>(data), size), "markers.yaml");
  } catch (const ddace::Error&) {
  }
  return 0;
}
