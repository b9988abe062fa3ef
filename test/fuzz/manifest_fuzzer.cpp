// libFuzzer target: a model's manifest.yaml is accepted or refused with a ddace::Error
// (never a crash, another exception, or an allocation sized by the file); an accepted
// manifest survives the writer and the reader again (files and fingerprint included), and
// asks for no more threads than a machine has (issue: `threads: 100000` made inspect and
// eval start 2,386 threads and hang). The task is test/fuzz/manifest_task.yaml. Parses
// from memory (tgn::files::parseManifest takes the text). Most inputs stop at the
// manifest's own digest: the corpus holds manifests sealed at ddace-model/17, both accepted
// (task4_scene.yaml, and task4_scene_plan.yaml, the same with every field of its training
// plan set: name groups, token by token, parked, load actions, an ensemble of 3, an end scene; reseal them
// at the current format, SHA-256 of every byte before the digest line, for the fuzzer to
// reach the field checks through its dictionary-free mutations of them);
// task4_scene_format9/7/6/5.yaml are older formats, refused with "retrain".
// fuzz-modules: task graph
// fuzz-sources: src/core/tgn/manifest.cpp src/core/tgn/plan_check.cpp
// fuzz-max-len: 16384
#include <cstdint>
#include <cstdlib>
#include <string>

#include "../../src/core/tgn/manifest.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"
#include "ddace/task/task_spec.h"

using namespace ddace;

// Far above any real machine: an accepted manifest asking for more is a missing range check.
constexpr int kMaxThreads = 1024;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const task::TaskSpec spec = task::parseTaskYaml(
      readTextFile(
          (ddace::findRepository("", {"test/fuzz/manifest_task.yaml"}) / "test/fuzz/manifest_task.yaml").string()),
      "task.yaml");
  const std::string text(reinterpret_cast<const char*>(data), size);
  tgn::ModelInfo info;
  try {
    info = tgn::files::parseManifest(text, "manifest.yaml", spec);
  } catch (const Error&) {
    return 0;
  }
  if (info.options.threads > kMaxThreads) std::abort();
  try {
    const tgn::ModelInfo again =
        tgn::files::parseManifest(tgn::files::manifestText(info, spec, info.files), "manifest.yaml", spec);
    if (again.files.size() != info.files.size() || !(again.fingerprint == info.fingerprint)) std::abort();
    for (const auto& [name, d] : info.files)
      if (again.files.at(name).sha256 != d.sha256 || again.files.at(name).bytes != d.bytes) std::abort();
  } catch (const Error&) {
    std::abort();  // ddace wrote a manifest it refuses
  }
  return 0;
}
