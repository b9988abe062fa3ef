// libFuzzer target: the demonstration CSV reader must reject or accept any bytes, never crash.
// What is accepted must survive the writer and the reader again exactly: the same times,
// positions and labels (a written number reads back as the same double). A text file has
// no NUL byte: an accepted input with one means a field was read only up to it
// (issue: "0.208496\0GARBAGE" was read as a number).
// fuzz-modules: task
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/task/demonstration.h"

using namespace ddace::task;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const TaskSpec spec = parseTaskYaml(
      "format: ddace-task/1\nentities:\n  - {name: R1, kind: robot}\n  - {name: B1, kind: object}\n"
      "  - {name: G1, kind: goal}\nactions: [move, carry]\n",
      "task.yaml");
  const std::string text(reinterpret_cast<const char*>(data), size);
  Demonstration demo;
  try {
    demo = parseDemonstrationCsv(text, spec, "fuzz.csv");
  } catch (const ddace::Error&) {
    return 0;
  }
  if (text.find('\0') != std::string::npos) std::abort();
  Demonstration again;
  try {
    again = parseDemonstrationCsv(demonstrationCsvText(demo, spec), spec, "again.csv");
  } catch (const ddace::Error&) {
    std::abort();  // ddace wrote a demonstration it refuses
  }
  if (again.t != demo.t || again.positions != demo.positions || again.labels != demo.labels) std::abort();
  return 0;
}
