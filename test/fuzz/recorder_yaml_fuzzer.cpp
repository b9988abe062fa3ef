// libFuzzer target: config/recorder.yaml (output directory, rates, the task's settings)
// is accepted or refused with a ddace::Error, never a crash or another exception. The
// markers are the shipped config/markers.yaml. An accepted config's task must survive
// the task.yaml writer and reader (the recorder writes it into the task directory).
// fuzz-modules: vision task label
// fuzz-max-len: 16384
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/task/task_spec.h"
#include "ddace/vision/recorder.h"
#include "ddace/vision/tracker.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const ddace::vision::MarkerConfig markers = ddace::vision::parseMarkerConfig(
      ddace::readTextFile((ddace::findRepository("", {"config/markers.yaml"}) / "config/markers.yaml").string()),
      "markers.yaml");
  ddace::vision::RecorderConfig config;
  try {
    config = ddace::vision::parseRecorderConfig(std::string(reinterpret_cast<const char*>(data), size), "recorder.yaml",
                                                markers);
  } catch (const ddace::Error&) {
    return 0;
  }
  try {
    ddace::task::parseTaskYaml(ddace::task::taskYamlText(config.spec), "task.yaml");
  } catch (const ddace::Error&) {
    std::abort();  // the recorder would write a task.yaml that ddace itself refuses
  }
  return 0;
}
