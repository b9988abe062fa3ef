// libFuzzer target: the task.yaml reader must reject or accept any bytes, never crash.
// fuzz-modules: task
#include <cstdint>
#include <string>

#include "ddace/task/task_spec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto spec = ddace::task::parseTaskYaml(std::string(reinterpret_cast<const char*>(data), size), "fuzz.yaml");
    ddace::task::parseTaskYaml(ddace::task::taskYamlText(spec), "again.yaml");
  } catch (const ddace::Error&) {
  }
  return 0;
}
