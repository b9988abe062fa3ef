// libFuzzer target: the synthetic camera's YAML (scene, camera pose, noise, occlusions)
// is accepted or refused with a ddace::Error, never a crash or another exception.
// fuzz-modules: vision task
// fuzz-max-len: 16384
#include <cstdint>
#include <string>

#include "ddace/common/error.h"
#include "ddace/vision/synthetic_camera.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    ddace::vision::parseSyntheticCameraConfig(std::string(reinterpret_cast<const char*>(data), size),
                                              "synthetic_camera.yaml");
  } catch (const ddace::Error&) {
  }
  return 0;
}
