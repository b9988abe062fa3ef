// libFuzzer target: the demonstration CSV reader must reject or accept any bytes, never crash.
// fuzz-modules: task
#include <cstdint>
#include <string>

#include "ddace/task/demonstration.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const ddace::task::TaskSpec spec = ddace::task::parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\n  - {name: B1, kind: object}\n"
      "  - {name: G1, kind: goal}\nactions: [move, carry]\n",
      "task.yaml");
  try {
    const auto demo = ddace::task::parseDemonstrationCsv(std::string(reinterpret_cast<const char*>(data), size),
                                                         spec, "fuzz.csv");
    // Whatever was accepted must round-trip through the writer.
    ddace::task::parseDemonstrationCsv(ddace::task::demonstrationCsvText(demo, spec), spec, "again.csv");
  } catch (const ddace::Error&) {
  }
  return 0;
}
