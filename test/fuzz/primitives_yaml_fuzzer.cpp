// libFuzzer target: a model's primitives.yaml (the fitted Gaussian-process library, with
// the task fingerprint it names) is parsed or refused with a ddace::Error, never a crash,
// another exception or an allocation sized by the file (-rss_limit_mb); an accepted
// library survives text() and parse() with the same fingerprint. Parses from memory
// (gp::PrimitiveLibrary::parse).
// fuzz-modules: gp task
// fuzz-max-len: 65536
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/common/error.h"
#include "ddace/gp/primitives.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  ddace::gp::PrimitiveLibrary lib;
  try {
    lib = ddace::gp::PrimitiveLibrary::parse(text, "primitives.yaml");
  } catch (const ddace::Error&) {
    return 0;
  }
  try {
    const auto again = ddace::gp::PrimitiveLibrary::parse(lib.text(), "primitives.yaml");
    if (!(again.taskFingerprint() == lib.taskFingerprint())) std::abort();
  } catch (const ddace::Error&) {
    std::abort();  // ddace wrote a library it refuses
  }
  return 0;
}
