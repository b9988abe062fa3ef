// libFuzzer target: an execution config (config/execution.yaml) as `ddace eval --config`
// reads it is accepted or refused with a ddace::Error, never a crash or another exception;
// what it accepts passes every parameter struct's own validate().
// fuzz-modules: exec task common
// fuzz-max-len: 16384
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/common/error.h"
#include "ddace/exec/execution_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ddace::exec::ExecutionConfig config;
  try {
    config =
        ddace::exec::parseExecutionConfig(std::string(reinterpret_cast<const char*>(data), size), "execution.yaml");
  } catch (const ddace::Error&) {
    return 0;
  }
  try {
    config.gains.validate();
    config.safety.validate();
    config.robot.validate();
    config.table.validate();
  } catch (const ddace::Error&) {
    std::abort();  // accepted, yet invalid
  }
  return 0;
}
