// libFuzzer target: a model's manifest.yaml is accepted or refused with a ddace::Error
// (never a crash, another exception, or an allocation sized by the file); an accepted
// manifest survives the writer and the reader again, and asks for no more threads than a
// machine has (issue: `threads: 100000` made inspect and eval start 2,386 threads and hang). The task is
// test/fuzz/manifest_task.yaml. The reader takes a path only (tgn::files::parseManifest): the input goes through an
// in-memory file. A text API (parseManifestText(text, file, spec, ...)) would let this
// parse from memory.
// fuzz-modules: task graph
// fuzz-sources: src/core/tgn/manifest.cpp
// fuzz-max-len: 16384
#include <cstdint>
#include <cstdlib>
#include <string>

#include "../../src/core/tgn/manifest.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/task/task_spec.h"
#include "memory_file.h"

using namespace ddace;

// Far above any real machine: an accepted manifest asking for more is a missing range check.
constexpr int kMaxThreads = 1024;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const task::TaskSpec spec = task::parseTaskYaml(
      readTextFile(
          (ddace::findRepository("", {"test/fuzz/manifest_task.yaml"}) / "test/fuzz/manifest_task.yaml").string()),
      "task.yaml");
  static MemoryFile file;
  tgn::ModelInfo info;
  uint64_t hash = 0, bytes = 0;
  try {
    info = tgn::files::parseManifest(file.hold(data, size), spec, &hash, &bytes);
  } catch (const Error&) {
    return 0;
  }
  if (info.options.threads > kMaxThreads) std::abort();
  try {
    uint64_t hash2 = 0, bytes2 = 0;
    tgn::files::parseManifest(file.hold(tgn::files::manifestText(info, spec, hash, bytes)), spec, &hash2, &bytes2);
    if (hash2 != hash || bytes2 != bytes) std::abort();
  } catch (const Error&) {
    std::abort();  // ddace wrote a manifest it refuses
  }
  return 0;
}
