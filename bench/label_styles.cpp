// bench_label_styles: token accuracy of `ddace label` on demonstrations made in other
// ways than the generators' (label::demonstrationStyles: one aspect of a person's motion
// varied at a time, then all at once), with bodies (motions end at contact, a pushed box
// rides in front of its pusher), on every family, the zoo's kinds of task and a sample of
// drawn zoo rules, in both of the zoo's motion models (benchFamilies).
//
// Per family, style and seed: `--demos` demonstrations moved in that style
// (label::humanMotion); the first labelled (the example), the others labelled from motion
// (label::inferredDataset). Reported: token accuracy (a cell: the worst over the seeds),
// the worst style of each family (not the mean), and how far the labeller's own doubt can
// be trusted: of the wrong tokens, the fraction listed to check; of the listed tokens, the
// fraction wrong, by the note that listed them; wrong demonstrations with nothing listed
// (what --strict would write silently).
// Writes docs/bench/label_styles.md under the repository (--repo DIR); --quick: four
// families, three styles, four demonstrations, the report on stdout (no file written).
// --osr: what the labels change downstream instead: the default network trained on the true
// labels, on the inferred ones, and on the usable inferred demonstrations only (20
// demonstrations, the first the example), OSR on 20 fresh scenes, ideal execution, for the
// issue's families in two styles (`all`, `pause`);
// writes docs/bench/label_styles_osr.md (with --family/--style: on stdout); each OSR over
// --train-seeds training seeds (3), their mean and range.
// Usage: ddace bench label_styles [--repo DIR] [--quick] [--demos N] [--seed S] [--seeds N
//        (seeds S..S+N-1, 3)] [--zoo N (drawn rules, 20)]
//        [--family F] [--style S] [--show] (one family or style, on stdout; --show: the
//        demonstrations labelled wrong, true and inferred steps) [--dump DIR] (the
//        demonstrations as moved, true labels, a task directory per style under DIR)
//        [--keyed] (true labels begin at each motion's own onset, as a person keys each
//        robot as it starts: HumanMotionOptions::label_at_own_onset) [--onset-spread S]
//        (styles that start a step's robots apart start them up to S seconds apart)
//        [--osr [--train-seeds N]]
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "ddace/common/error.h"
#include "ddace/label/human_motion.h"
#include "ddace/pipeline/evaluation.h"
#include "ddace/tasks/generators.h"
#include "ddace/tasks/rule_zoo.h"
#include "results.h"

using namespace ddace;

namespace {

struct Family {
  std::string name, description;
};

constexpr const char* kOccupiedFamily = label::kOccupiedGoalFamily;

task::TaskDir generated(const std::string& family, int demos, uint64_t seed) {
  if (family == kOccupiedFamily) return label::occupiedGoalFamily(demos, seed);
  uint64_t id = 0;
  tasks::ZooMotion motion;
  if (tasks::parseZooFamily(family, id, &motion)) return tasks::generateZoo(id, demos, seed, motion);
  tasks::GeneratorOptions o;
  o.family = family;
  o.demos = demos;
  o.seed = seed;
  return tasks::generate(o);
}

std::string stepsText(const task::Demonstration& d, const task::TaskSpec& spec) {
  std::string s;
  for (const auto& step : d.steps) {
    s += " [";
    for (size_t i = 0; i < step.tokens.size(); ++i) s += (i ? " " : "") + task::tokenKey(step.tokens[i], spec);
    s += "]";
  }
  return s;
}

std::string fixed(double v, int digits = 2) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

/// OSR of the default network trained on `data`'s true labels, its inferred ones, and its
/// usable inferred demonstrations only (nothing listed: what a user keeps without reviewing),
/// on `test`; a model that evaluation refuses (its tokens never demonstrated) is -1, `why`
/// says why.
struct OsrCells {
  double truth = -1, inferred = -1, usable = -1;
  int usable_demos = 0;
  std::string why;
};

OsrCells trainedOsr(const label::InferredDataset& data, const task::TaskDir& test, const std::filesystem::path& scratch,
                    uint64_t seed) {
  tgn::TrainOptions options;
  options.seed = seed;
  OsrCells out;
  task::TaskDir usable = data.inferred;
  usable.demos.clear();
  for (size_t d = 0; d < data.inferred.demos.size(); ++d)
    if (d == 0 || data.notes[d].empty()) usable.demos.push_back(data.inferred.demos[d]);
  out.usable_demos = static_cast<int>(usable.demos.size());
  const std::vector<std::pair<std::string, std::pair<const task::TaskDir*, double*>>> runs = {
      {"true labels", {&data.truth, &out.truth}},
      {"inferred labels", {&data.inferred, &out.inferred}},
      {"usable demonstrations", {&usable, &out.usable}}};
  for (const auto& [name, run] : runs) {
    const std::filesystem::path dir = scratch / "model";
    try {
      const pipeline::Model model = pipeline::trainModel(*run.first, options, dir, nullptr);
      *run.second = pipeline::evaluate(model, test, {}).summary.osr;
    } catch (const Error& e) {
      out.why += name + ": " + e.what() + "; ";
    }
    std::filesystem::remove_all(dir);
  }
  return out;
}

/// One OSR cell over training seeds: their mean and range; "refused" when a seed's model was.
struct SeedCell {
  std::vector<double> runs;
  void add(double v) { runs.push_back(v); }
  bool refused() const {
    return std::any_of(runs.begin(), runs.end(), [](double v) { return v < 0; });
  }
  double mean() const {
    double sum = 0;
    for (const double v : runs) sum += v;
    return runs.empty() ? -1 : sum / static_cast<double>(runs.size());
  }
  std::string text() const {
    if (runs.empty() || refused()) return "refused";
    if (runs.size() == 1) return fixed(runs[0]);
    return fixed(mean()) + " (" + fixed(*std::min_element(runs.begin(), runs.end())) + "-" +
           fixed(*std::max_element(runs.begin(), runs.end())) + ")";
  }
};

/// The families (docs/labels.md, "Measured"), trained on inferred and true labels
/// with training seeds seed .. seed + train_seeds - 1.
int osrBench(const std::filesystem::path& repo, const std::string& only_family, const std::string& only_style,
             uint64_t seed, int train_seeds) {
  std::vector<std::string> families = {"task4", "fetch", "zoo:140", "zoo:left-to-right", "zoo:87", kOccupiedFamily};
  if (!only_family.empty()) families = {only_family};
  std::vector<label::DemonstrationStyle> styles;
  const auto all = label::demonstrationStyles();
  for (size_t k = 0; k < all.size(); ++k)
    if (only_style.empty() ? all[k].name == "all" || all[k].name == "pause" : all[k].name == only_style)
      styles.push_back(all[k]);
  if (styles.empty()) throw Error("--style " + only_style + ": no such style");
  const int demos = 20, test_demos = 20;
  const std::filesystem::path scratch =
      std::filesystem::temp_directory_path() / ("ddace_bench_label_styles_" + std::to_string(getpid()));
  std::ostringstream table;
  table << "| family | style | token accuracy | OSR, true labels | OSR, inferred labels | difference | usable "
           "demonstrations | OSR, usable only |\n"
        << "|---|---|---|---|---|---|---|---|\n";
  double worst = 0;
  std::string refused;
  for (const auto& f : families) {
    const task::TaskDir dir = generated(f, demos, seed);
    // Fresh scenes, as `ddace generate` draws a test set.
    const task::TaskDir test = generated(f, test_demos, seed * 2654435761ULL + 0x7e57);
    for (const auto& st : styles) {
      const label::InferredDataset data = label::inferredDataset(dir, st.options, label::styleSeed(seed, st.name));
      SeedCell truth, inferred, usable;
      int usable_demos = 0;
      for (int ts = 0; ts < train_seeds; ++ts) {
        const OsrCells osr = trainedOsr(data, test, scratch, seed + static_cast<uint64_t>(ts));
        truth.add(osr.truth), inferred.add(osr.inferred), usable.add(osr.usable);
        usable_demos = osr.usable_demos;
        if (!osr.why.empty()) refused += "- " + f + ", " + st.name + ": " + osr.why + "\n";
      }
      const bool both = !truth.refused() && !inferred.refused();
      const double diff = both ? inferred.mean() - truth.mean() : -1;
      if (both) worst = std::min(worst, diff);
      table << "| " << f << " | " << st.name << " | " << fixed(data.score.accuracy()) << " | " << truth.text() << " | "
            << inferred.text() << " | " << (both ? (diff >= 0 ? "+" : "") + fixed(diff) : std::string("-")) << " | "
            << usable_demos << " of " << data.inferred.demos.size() << " | " << usable.text() << " |\n";
      std::cout << f << " " << st.name << ": accuracy " << fixed(data.score.accuracy(), 3) << ", OSR true "
                << truth.text() << ", inferred " << inferred.text() << ", usable only " << usable.text() << " ("
                << usable_demos << " demonstrations)\n"
                << std::flush;
    }
  }
  std::ostringstream md;
  md << "# OSR from labels inferred in other styles\n\n"
     << "Written by `ddace bench label_styles --osr` (bench/label_styles.cpp). Do not edit.\n\n"
     << "Each family: " << demos << " demonstrations (seed " << seed
     << ", with bodies) moved in the style (`label::humanMotion`), the first labelled by hand (the example), the "
        "others labelled from their motion (`label::inferredDataset`). The default network (`ddace train`'s "
        "defaults, training seeds "
     << seed << "-" << seed + static_cast<uint64_t>(train_seeds) - 1
     << ") is trained on the true labels, on the inferred ones, and on the usable inferred demonstrations only (the "
        "example and those with nothing listed: what a user keeps without reviewing any), and evaluated on "
     << test_demos
     << " fresh scenes (ideal execution). A cell: the mean over the training seeds (lowest-highest); the "
        "difference: of the means. The seed alone moves OSR by a few hundredths where few demonstrations leave "
        "the network undecided (docs/labels-log.md).\n\n"
     << table.str() << "\nLargest drop, inferred below true: " << fixed(std::max(0.0, -worst))
     << " (goal: within 0.05).\n";
  if (!refused.empty()) md << "\nRefused:\n\n" << refused;
  if (!only_family.empty() || !only_style.empty()) std::cout << md.str();
  else bench::writeResults(repo, "label_styles_osr", md.str());
  return 0;
}

/// A table of the report: its families and what they are.
struct FamilyGroup {
  std::string title;
  std::vector<Family> families;
};

/// The second-nearest robot fetches B1 and carries it to G1 (the families lack it
/// among the zoo's kinds).
constexpr const char* kSecondNearestFetch = "zoo:27";

/// What the full run measures: the generators' families and the zoo's kinds in the
/// generators' motion; the zoo's kinds (and the second-nearest fetch) in each direct
/// motion; and `zoo_sample` distinct drawn rules, each in the generators' motion and in one
/// direct motion (cycling through touching, 4 mm and 1 cm short).
std::vector<FamilyGroup> benchFamilies(int zoo_sample) {
  FamilyGroup gen{"Moved as the generators move (paths bent around bodies, stops touching)", {}};
  for (const auto& f : tasks::allFamilies()) gen.families.push_back({f, "`ddace generate " + f + "`"});
  std::vector<Family> kinds;
  for (const auto& k : tasks::userKinds()) kinds.push_back({k.family, k.kind});
  kinds.push_back({kSecondNearestFetch, tasks::zooRule(27).name});
  gen.families.insert(gen.families.end(), kinds.begin(), kinds.end());
  gen.families.push_back({kOccupiedFamily, "fetch, then the other robot to the goal the box occupies"});
  FamilyGroup direct{
      "The zoo's kinds moved directly (paths straight or arcs, bent around nothing; stops touching, 4 "
      "mm or 1 cm short)",
      {}};
  for (const auto& m : tasks::directZooMotions())
    for (const auto& k : kinds) direct.families.push_back({k.name + m.suffix(), k.description + ", " + m.words()});
  FamilyGroup sample{"A sample of the zoo: the first " + std::to_string(zoo_sample) +
                         " distinct drawn rules, in the generators' motion and in one direct motion",
                     {}};
  const auto motions = tasks::directZooMotions();
  size_t n = 0;
  for (const uint64_t id : tasks::distinctZooRules(zoo_sample)) {
    const std::string family = "zoo:" + std::to_string(id);
    const tasks::ZooMotion m = motions[n++ % motions.size()];
    sample.families.push_back({family, tasks::zooRule(id).name});
    sample.families.push_back({family + m.suffix(), tasks::zooRule(id).name + ", " + m.words()});
  }
  return {gen, direct, sample};
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const auto repo = bench::repositoryFromArgs(argc, argv);
    bool quick = false, show = false, osr = false, keyed = false;
    double onset_spread = 0;
    std::string only_family, only_style, dump;
    int demos = 10, train_seeds = 3, seeds = 3, zoo_sample = 20;
    uint64_t seed = 1;
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--quick") {
        quick = true;
      } else if (a == "--demos" && i + 1 < argc) {
        demos = std::atoi(argv[++i]);
        if (demos < 2 || demos > 200) throw Error("--demos must be 2..200 (got '" + std::string(argv[i]) + "')");
      } else if (a == "--seeds" && i + 1 < argc) {
        seeds = std::atoi(argv[++i]);
        if (seeds < 1 || seeds > 20) throw Error("--seeds must be 1..20 (got '" + std::string(argv[i]) + "')");
      } else if (a == "--zoo" && i + 1 < argc) {
        zoo_sample = std::atoi(argv[++i]);
        if (zoo_sample < 0 || zoo_sample > 200)
          throw Error("--zoo must be 0..200 (got '" + std::string(argv[i]) + "')");
      } else if (a == "--family" && i + 1 < argc) {
        only_family = argv[++i];
      } else if (a == "--style" && i + 1 < argc) {
        only_style = argv[++i];
      } else if (a == "--show") {
        show = true;
      } else if (a == "--dump" && i + 1 < argc) {
        dump = argv[++i];
      } else if (a == "--keyed") {
        keyed = true;
      } else if (a == "--onset-spread" && i + 1 < argc) {
        onset_spread = std::atof(argv[++i]);
        if (!(onset_spread > 0 && onset_spread <= 5))
          throw Error("--onset-spread must be in (0, 5] seconds (got '" + std::string(argv[i]) + "')");
      } else if (a == "--osr") {
        osr = true;
      } else if (a == "--train-seeds" && i + 1 < argc) {
        train_seeds = std::atoi(argv[++i]);
        if (train_seeds < 1 || train_seeds > 10)
          throw Error("--train-seeds must be 1..10 (got '" + std::string(argv[i]) + "')");
      } else if (a == "--seed" && i + 1 < argc) {
        seed = std::strtoull(argv[++i], nullptr, 10);
      } else {
        throw Error(
            "usage: bench_label_styles [--repo DIR] [--quick] [--demos N] [--seed S] [--seeds N] [--zoo N] [--family "
            "F] [--style S] [--show] [--dump DIR] [--keyed] [--onset-spread S] [--osr [--train-seeds N]] (got '" +
            a + "')");
      }
    }
    if (osr) return osrBench(repo, only_family, only_style, seed, train_seeds);
    std::vector<FamilyGroup> groups = benchFamilies(zoo_sample);
    std::vector<label::DemonstrationStyle> styles = label::demonstrationStyles();
    if (quick) {
      groups = {{"Quick",
                 {{"fetch", "fetch"},
                  {"zoo:87", "relay"},
                  {kOccupiedFamily, "occupied goal"},
                  {"zoo:140/direct-10mm", "farthest fetches, direct, 1 cm short"}}}};
      std::vector<label::DemonstrationStyle> some;
      for (const auto& s : styles)
        if (s.name == "calm" || s.name == "pause" || s.name == "all") some.push_back(s);
      styles = some;
      demos = 4;
    }
    // One family or style (a look at what went wrong: --show prints the demonstrations
    // labelled wrong, their true and inferred steps), the report on stdout.
    if (!only_family.empty() || !only_style.empty()) {
      quick = true;
      if (!only_family.empty()) groups = {{only_family, {{only_family, only_family}}}};
      std::vector<label::DemonstrationStyle> some;
      for (const auto& st : styles)
        if (only_style.empty() || st.name == only_style) some.push_back(st);
      if (some.empty()) throw Error("--style " + only_style + ": no such style");
      styles = some;
    }

    for (auto& st : styles) {
      st.options.label_at_own_onset = keyed;
      if (onset_spread > 0 && st.options.onset_spread_s > 0) st.options.onset_spread_s = onset_spread;
    }

    std::ostringstream md;
    label::LabelScore total;
    std::vector<label::LabelScore> by_style(styles.size());
    std::vector<std::pair<std::string, label::LabelScore>> by_family;
    std::string not_generated;
    double worst_all = 1;
    int cells = 0, cells_below = 0;
    const uint64_t last_seed = seed + static_cast<uint64_t>(seeds) - 1;
    std::vector<std::string> tables;
    for (const FamilyGroup& group : groups) {
      std::ostringstream table;
      table << "| family |";
      for (const auto& s : styles) table << " " << s.name << " |";
      table << " worst |\n|---|";
      for (size_t i = 0; i <= styles.size(); ++i) table << "---|";
      table << "\n";
      for (const Family& f : group.families) {
        std::vector<double> cell(styles.size(), 2);
        label::LabelScore family_score;
        bool generated_all = true;
        for (uint64_t s = seed; s <= last_seed && generated_all; ++s) {
          task::TaskDir dir;
          try {
            dir = generated(f.name, demos, s);
          } catch (const Error& e) {
            not_generated += "- " + f.name + " (seed " + std::to_string(s) + "): " + e.what() + "\n";
            generated_all = false;
            break;
          }
          for (size_t k = 0; k < styles.size(); ++k) {
            const label::InferredDataset data =
                label::inferredDataset(dir, styles[k].options, label::styleSeed(s, styles[k].name));
            const double acc = data.score.accuracy();
            if (!dump.empty()) task::writeTaskDir(data.truth, dump + "/" + styles[k].name);
            for (size_t d = 1; show && d < data.truth.demos.size(); ++d)
              if (!task::sameSteps(data.truth.demos[d].steps, data.inferred.demos[d].steps))
                std::cout << "seed " << s << " demo " << d
                          << "\n  true:    " << stepsText(data.truth.demos[d], dir.spec)
                          << "\n  inferred:" << stepsText(data.inferred.demos[d], dir.spec) << "\n";
            for (size_t d = 1; show && d < data.notes.size(); ++d)
              for (const auto& n : data.notes[d])
                std::cout << "  seed " << s << " demo " << d << " line " << n.row + 2 << ": " << n.message << "\n";
            cell[k] = std::min(cell[k], acc);
            by_style[k].add(data.score);
            family_score.add(data.score);
            total.add(data.score);
            std::cout << f.name << " " << styles[k].name << " seed " << s << ": accuracy " << fixed(acc, 3)
                      << ", wrong " << data.score.wrong << " (listed " << data.score.wrong_listed << "), listed "
                      << data.score.listed << "\n"
                      << std::flush;
          }
        }
        if (!generated_all) continue;
        by_family.push_back({f.name, family_score});
        table << "| " << f.name << " |";
        double worst = 2;
        std::string worst_style;
        for (size_t k = 0; k < styles.size(); ++k) {
          table << " " << fixed(cell[k]) << " |";
          ++cells;
          if (cell[k] < 0.95 - 1e-9) ++cells_below;
          if (cell[k] < worst) worst = cell[k], worst_style = styles[k].name;
        }
        worst_all = std::min(worst_all, worst);
        table << " " << fixed(worst) << " (" << worst_style << ") |\n";
      }
      tables.push_back(table.str());
    }

    md << "# Labelling demonstrations made in other styles\n\n"
       << "Written by `ddace bench label_styles" << (quick ? " --quick" : "")
       << "` (bench/label_styles.cpp). Do not edit.\n\n"
       << "Each family is generated (" << demos << " demonstrations, seeds " << seed << "-" << last_seed
       << ", with bodies: motions end at contact, a pushed box rides in front of its pusher), moved in each style "
          "(`label::humanMotion`), its first demonstration labelled (the example) and the others labelled from "
          "their motion (`label::inferredDataset`). Token accuracy: matched tokens / max(true, inferred); a cell is "
          "one family in one style, the worst over the seeds; `worst` is the family's worst style.\n\n"
       << "Families: the generators' (`ddace generate`), the zoo's kinds of task (docs/tgn.md) and the "
          "second-nearest fetch ("
       << kSecondNearestFetch << "), " << kOccupiedFamily
       << " (bench/label_styles.cpp: fetch, then the other robot to the goal the box occupies); the zoo's kinds "
          "again in the zoo's second motion model (`zoo:<id>/direct`, `/direct-4mm`, `/direct-10mm`: paths straight "
          "or arcs, bent around nothing, stopping touching, 4 mm or 1 cm short of a body); and a sample of drawn "
          "zoo rules in both motion models.\n\n"
       << "Styles (`label::demonstrationStyles`, each varying one aspect of `calm`):\n\n";
    for (const auto& s : styles) md << "- `" << s.name << "`: " << s.description << "\n";
    for (size_t g = 0; g < groups.size(); ++g) md << "\n## " << groups[g].title << "\n\n" << tables[g];
    md << "\nWorst cell: " << fixed(worst_all) << "; cells below 0.95: " << cells_below << " of " << cells
       << " (goal: at least 0.95 in every cell).\n";
    if (!not_generated.empty()) md << "\nNot generated (the zoo finds no scene for the rule):\n\n" << not_generated;
    md << "\n## Doubt\n\nTokens listed to check (`ddace label` prints them and `--strict` refuses them). Recall: of "
          "the wrong tokens, the fraction listed; precision: of the listed tokens, the fraction wrong.\n\n"
       << "| style | wrong tokens | of them listed | listed tokens | of them wrong | wrong demos | of them with "
          "nothing listed |\n|---|---|---|---|---|---|---|\n";
    auto doubtRow = [&](const std::string& name, const label::LabelScore& s) {
      md << "| " << name << " | " << s.wrong << " | " << fixed(s.wrongListed()) << " | " << s.listed << " | "
         << fixed(s.listedWrong()) << " | " << s.demos_wrong << " | " << s.demos_wrong - s.demos_wrong_listed << " |\n";
    };
    for (size_t k = 0; k < styles.size(); ++k) doubtRow(styles[k].name, by_style[k]);
    doubtRow("every style", total);
    md << "\nListed tokens by the note that listed them (its fixed words; `docs/labels.md`, \"Reported for the person "
          "to check\"), over every family and style:\n\n| note | listed tokens | of them wrong |\n|---|---|---|\n";
    for (const auto& [kind, n] : total.listed_by_doubt)
      md << "| " << kind << " | " << n[0] << " | " << fixed(n[0] ? static_cast<double>(n[1]) / n[0] : 0.0) << " |\n";
    md << "\nThe same per family, over every style (families with nothing wrong and nothing listed left out):\n\n"
       << "| family | wrong tokens | of them listed | listed tokens | of them wrong | wrong demos | of them with "
          "nothing listed |\n|---|---|---|---|---|---|---|\n";
    for (const auto& [name, score] : by_family)
      if (score.wrong > 0 || score.listed > 0) doubtRow(name, score);
    md << "\nGoal: at least 0.90 of the wrong tokens listed, no wrong demonstration with nothing listed.\n";
    std::cout << "worst cell " << fixed(worst_all) << ", wrong " << total.wrong << " (listed " << total.wrong_listed
              << "), listed " << total.listed << ", recall " << fixed(total.wrongListed()) << ", precision "
              << fixed(total.listedWrong()) << "\n";
    if (quick) std::cout << md.str();  // a smoke run: the results file keeps the full run
    else bench::writeResults(repo, "label_styles", md.str());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "bench_label_styles: " << e.what() << "\n";
    return 1;
  }
}
