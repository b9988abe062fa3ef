// ddace bench: run the benchmarks (bench/<name>.cpp -> bench_<name>, installed next to ddace).
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "command.h"
#include "ddace/common/error.h"
#include "ddace/common/repository.h"

namespace ddace::cli {
namespace {

namespace fs = std::filesystem;

/// `a` quoted for /bin/sh.
std::string shellQuoted(const std::string& a) {
  std::string q = "'";
  for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

int runBench(const std::vector<std::string>& argv) {
  // ddace bench's own arguments (NAME..., --list, --repo DIR) and, from the first other
  // --option on, the options of the one benchmark named, handed to it as they are
  // (`ddace bench label_memory --mb 1024`); each benchmark refuses what it does not take.
  std::vector<std::string> own, passed;
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string flag = argv[i].substr(0, argv[i].find('='));  // --repo=DIR as Args reads it
    if (flag == "--repo" || flag == "--list") {
      own.push_back(argv[i]);
      if (argv[i] == "--repo" && i + 1 < argv.size()) own.push_back(argv[++i]);
    } else if (!passed.empty() || argv[i].rfind("--", 0) == 0) {
      passed.push_back(argv[i]);
    } else {
      own.push_back(argv[i]);
    }
  }
  Args args(own, {"--repo"}, {"--list"});
  const fs::path self = fs::read_symlink("/proc/self/exe");
  std::vector<fs::path> benches;
  for (const auto& entry : fs::directory_iterator(self.parent_path())) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("bench_", 0) == 0 && access(entry.path().c_str(), X_OK) == 0) benches.push_back(entry.path());
  }
  std::sort(benches.begin(), benches.end());
  if (args.has("--list")) {
    if (!passed.empty())
      throw Error("ddace bench --list runs nothing: the options " + passed.front() + " ... would be lost");
    for (const auto& b : benches) std::cout << b.filename().string().substr(6) << "\n";
    return 0;
  }
  std::vector<fs::path> chosen;
  for (const auto& want : args.positional()) {
    auto it = std::find_if(benches.begin(), benches.end(),
                           [&](const fs::path& b) { return b.filename() == "bench_" + want; });
    if (it == benches.end()) throw Error("unknown benchmark '" + want + "' (ddace bench --list shows them)");
    chosen.push_back(*it);
  }
  if (!passed.empty() && chosen.size() != 1)
    throw Error("ddace bench: options for a benchmark (" + passed.front() +
                ") need exactly one benchmark named before them, e.g. ddace bench label_memory --mb 1024");
  if (chosen.empty()) chosen = benches;
  if (chosen.empty()) throw Error("no benchmarks built next to " + self.string());
  // Every benchmark writes into the same repository: found once here (an error before any
  // run when there is none), handed to each through DDACE_REPO.
  const fs::path repo = findRepository(args.get("--repo", ""), {"docs/bench"});
  ::setenv(kRepositoryEnv, repo.c_str(), 1);
  int failed = 0;
  for (const auto& b : chosen) {
    std::cout << "== " << b.filename().string().substr(6) << "\n" << std::flush;
    std::string command = shellQuoted(b.string());
    for (const auto& a : passed) command += " " + shellQuoted(a);
    const int rc = std::system(command.c_str());
    if (rc != 0) {
      std::cerr << "ddace bench: " << b.filename().string() << " exited with status " << rc << "\n";
      ++failed;
    }
  }
  std::cout << "results: " << (repo / "docs" / "bench").string() << "/*.md\n";
  return failed ? 1 : 0;
}

DDACE_COMMAND({"bench",
               "ddace bench [NAME...] [--list] [--repo DIR] | ddace bench NAME [--repo DIR] [BENCH-OPTIONS...]",
               "run the benchmarks (all by default); each writes docs/bench/<name>.md of the repository. Options "
               "after one NAME go to that benchmark (ddace bench label_memory --mb 1024)",
               runBench});

}  // namespace
}  // namespace ddace::cli
