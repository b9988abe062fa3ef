// libFuzzer target: a model's loss.csv is accepted or refused with a ddace::Error, never
// a crash; what is accepted survives the writer and the reader again unchanged.
// The reader takes a path only (tgn::files::readLossCsv): the input goes through an
// in-memory file. A text API (parseLossCsv(text, file)) would let this parse from memory.
// fuzz-modules: task graph
// fuzz-sources: src/core/tgn/manifest.cpp src/core/tgn/plan_check.cpp
#include <cstdint>
#include <cstdlib>
#include <string>

#include "../../src/core/tgn/manifest.h"
#include "ddace/common/error.h"
#include "memory_file.h"

using namespace ddace::tgn;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static MemoryFile file;
  std::vector<EpochRecord> history;
  try {
    history = files::readLossCsv(file.hold(data, size));
  } catch (const ddace::Error&) {
    return 0;
  }
  std::vector<EpochRecord> again;
  try {
    again = files::readLossCsv(file.hold(files::lossCsvText(history)));
  } catch (const ddace::Error&) {
    std::abort();  // ddace wrote a loss.csv it refuses
  }
  if (again.size() != history.size()) std::abort();
  for (size_t i = 0; i < again.size(); ++i)
    if (again[i].epoch != history[i].epoch || again[i].loss != history[i].loss) std::abort();
  return 0;
}
