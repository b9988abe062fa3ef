// libFuzzer target: a model's primitives.yaml (the fitted Gaussian-process library) is
// loaded or refused with a ddace::Error, never a crash, another exception or an allocation
// sized by the file (-rss_limit_mb); an accepted library survives save() and load().
// The reader takes a path only (gp::PrimitiveLibrary::load): the input goes through an
// in-memory file. A text API (PrimitiveLibrary::parse(text, file)) would let this parse
// from memory.
// fuzz-modules: gp task
// fuzz-max-len: 65536
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/common/error.h"
#include "ddace/gp/primitives.h"
#include "memory_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static MemoryFile file;
  static MemoryFile saved;
  try {
    const auto lib = ddace::gp::PrimitiveLibrary::load(file.hold(data, size));
    saved.hold(nullptr, 0);
    lib.save(saved.path());
  } catch (const ddace::Error&) {
    return 0;
  }
  try {
    ddace::gp::PrimitiveLibrary::load(saved.path());
  } catch (const ddace::Error&) {
    std::abort();  // ddace wrote a library it refuses
  }
  return 0;
}
