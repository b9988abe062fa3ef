// libFuzzer target: config/hamsters.yaml (the bridge's robots, ports and calibration) is
// accepted or refused with a ddace::Error, never a crash or another exception.
// fuzz-modules: hamster
// fuzz-max-len: 16384
#include <cstdint>
#include <string>

#include "ddace/common/error.h"
#include "ddace/hamster/config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    ddace::hamster::parseBridgeConfig(std::string(reinterpret_cast<const char*>(data), size), "hamsters.yaml");
  } catch (const ddace::Error&) {
  }
  return 0;
}
