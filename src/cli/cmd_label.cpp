// ddace label: infer the labels of unlabelled demonstrations from their motion
// (docs/labels.md). IN is only read; OUT gets task.yaml as it is and labelled copies.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/label/recording.h"
#include "ddace/task/owned_dir.h"
#include "ddace/task/summary.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

/// True when `inner` is `outer` or below it (after resolving what exists of both).
bool within(const fs::path& inner, const fs::path& outer) {
  const fs::path a = fs::weakly_canonical(fs::absolute(inner)), b = fs::weakly_canonical(fs::absolute(outer));
  auto ia = a.begin(), ib = b.begin();
  for (; ib != b.end(); ++ia, ++ib) {
    if (ib->empty()) continue;  // a trailing separator
    if (ia == a.end() || *ia != *ib) return false;
  }
  return true;
}

/// A step as its tokens: "[R1:move:G1 R2:move:G2]".
std::string stepText(const label::InferredStep& step, const task::TaskSpec& spec) {
  std::string s = "[";
  for (size_t i = 0; i < step.tokens.size(); ++i) s += (i ? " " : "") + task::tokenKey(step.tokens[i].token, spec);
  return s + "]";
}

/// Where a demonstration's copy goes in the output directory being written (`tmp`).
std::string inDemos(const std::string& tmp, const task::DemonstrationSummary& d) {
  return (fs::path(tmp) / "demos" / fs::path(d.source).filename()).string();
}

int runLabel(const std::vector<std::string>& argv) {
  Args args(argv, {"--out", "--example"}, {"--strict", "--force"});
  args.expectAtMostPositional(1);
  const std::string in = args.positional(0, "IN (the task directory of unlabelled demonstrations)");
  const std::string out = args.require("--out");
  if (within(out, in))
    throw Error("--out " + out + " is " + (within(in, out) ? "IN itself" : "inside IN (" + in + ")") +
                ": ddace label never writes into its input; choose another directory");

  // The same checks as `ddace validate`, reading every file as a stream.
  const task::TaskDirSummary dir = task::summarizeTaskDir(in);
  if (!dir.errors.empty()) throw Error(dir.errors);
  const task::TaskSpec& spec = dir.spec;
  if (dir.demos.empty()) throw Error(Diagnostic{in, 0, 0, "no demonstrations in demos/ to label"});
  // A labelled demonstration (the recorder's, or one labelled by hand) is kept as it is:
  // only the unlabelled ones are inferred, so a directory of both loses nothing.
  std::vector<const task::DemonstrationSummary*> unlabelled, labelled;
  for (const auto& d : dir.demos) (d.steps.empty() ? unlabelled : labelled).push_back(&d);
  if (unlabelled.empty())
    throw Error(Diagnostic{
        in, 0, 0,
        "every demonstration is already labelled (" + std::to_string(labelled.size()) +
            "): nothing for ddace label to infer. The recorder labels what it records when its recorder.yaml says "
            "infer_labels: true (the default): check them with ddace validate and train on " +
            in + " itself; scripts/label_keyboard.py --review FILE corrects one"});
  for (const auto* d : labelled)
    std::cout << fs::path(d->source).filename().string() << ": already labelled (" << d->steps.size()
              << " steps): copied as it is\n";

  std::optional<label::Example> example;
  if (args.has("--example")) {
    const std::string path = args.get("--example", "");
    example = label::Example::fromDemonstration(task::readDemonstrationCsv(path, spec), spec);
  }

  // Pass 1: infer every demonstration, report what is uncertain. The tokens go to a
  // temporary file as they are decided, so memory does not grow with a recording's length.
  constexpr size_t kShownSteps = 12;  // a long recording has thousands
  label::TokenSpill spill;
  std::vector<label::RecordingInference> inferred;
  std::vector<size_t> spill_from;
  size_t notes = 0;
  std::vector<std::string> to_review;  // demonstrations with something to check
  for (const task::DemonstrationSummary* demo : unlabelled) {
    const task::DemonstrationSummary& d = *demo;
    spill_from.push_back(spill.size());
    std::string shown;
    size_t steps = 0, unsure = 0;
    inferred.push_back(label::inferRecording(
        d.source, spec, example ? &*example : nullptr,
        [&](label::InferredStep&& step) {
          spill.add(step);
          for (const auto& t : step.tokens) unsure += t.unsure;
          if (steps++ < kShownSteps) shown += " " + stepText(step, spec);
        },
        [&](label::Note&& n) { std::cerr << d.source << ":" << n.row + 2 << ": " << n.message << "\n"; }));
    const std::string name = fs::path(d.source).filename().string();
    const size_t demo_notes = inferred.back().notes;
    std::cout << name << ": " << steps << " steps:" << shown << (steps > kShownSteps ? " ..." : "") << "; "
              << (demo_notes ? "to review (" + std::to_string(unsure) + " token(s) listed, " +
                                   std::to_string(demo_notes) + " item(s))"
                             : std::string("usable"))
              << "\n";
    if (demo_notes) to_review.push_back(name);
    notes += demo_notes;
  }
  spill_from.push_back(spill.size());
  std::cout << unlabelled.size() - to_review.size() << " of " << unlabelled.size() << " demonstrations usable";
  for (size_t i = 0; i < to_review.size(); ++i) std::cout << (i ? ", " : "; to review: ") << to_review[i];
  std::cout << "\n";
  if (notes > 0 && args.has("--strict")) {
    std::cerr << "ddace label: " << notes << " uncertain item(s) above; --strict: nothing written\n";
    return 1;
  }

  // Pass 2: task.yaml as it is, labelled copies of the demonstrations, checked as they are read back.
  task::writeOwnedDirectory(
      out,
      [&](const std::string& tmp) {
        fs::create_directories(fs::path(tmp) / "demos");
        writeTextFile((fs::path(tmp) / "task.yaml").string(), readTextFile((fs::path(in) / "task.yaml").string()));
        for (const auto* d : labelled) fs::copy_file(d->source, inDemos(tmp, *d));  // byte for byte, of any size
        for (size_t i = 0; i < unlabelled.size(); ++i) {
          const std::string target = inDemos(tmp, *unlabelled[i]);
          OutputFile file(target);
          label::LabelCursor cursor(spill.reader(spill_from[i], spill_from[i + 1]), spec.entities.size());
          label::writeLabelledRecording(unlabelled[i]->source, spec, inferred[i].labelled, cursor, file.stream());
          file.commit();
          // Counting the steps only: memory independent of the recording's steps too.
          const task::DemonstrationSummary back = task::summarizeDemonstrationCsv(target, spec, false);
          if (back.step_count != inferred[i].steps)
            throw Error(Diagnostic{target, 0, 0,
                                   "reads back with " + std::to_string(back.step_count) + " steps, inferred " +
                                       std::to_string(inferred[i].steps) + " (a bug in ddace label)"});
        }
      },
      "ddace label", args.has("--force"));
  std::cout << "wrote " << out << ": " << unlabelled.size() << " labelled demonstrations"
            << (labelled.empty() ? std::string() : " and " + std::to_string(labelled.size()) + " copied as they were")
            << (notes ? ", " + std::to_string(notes) + " item(s) to check (above)" : std::string()) << "\n";
  return 0;
}

}  // namespace

DDACE_COMMAND({"label", "ddace label IN --out OUT [--example CSV] [--strict] [--force]",
               "infer the labels of unlabelled demonstrations from their motion, writing a labelled copy of IN "
               "(its labelled demonstrations copied as they are; --example: words from a demonstration labelled by "
               "hand, before task.yaml's action_rules; --strict: "
               "write nothing when anything is uncertain; docs/labels.md)",
               runLabel});

}  // namespace ddace::cli
