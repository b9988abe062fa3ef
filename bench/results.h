// Where a benchmark reads the repository and writes its results: docs/bench/<name>.md of
// the repository ddace::findRepository finds (--repo DIR, DDACE_REPO, the directories
// above, the package path), written atomically through common/file.h.
#pragma once

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "ddace/common/error.h"
#include "ddace/common/file.h"
#include "ddace/common/repository.h"

namespace ddace::bench {

/// Takes "--repo DIR" out of argv (argc shrinks) and returns the repository: DIR or the
/// one found, holding docs/bench and `needs`. Throws ddace::Error naming what is missing.
inline std::filesystem::path repositoryFromArgs(int& argc, char** argv, std::vector<std::string> needs = {}) {
  std::string given;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--repo") {
      if (i + 1 >= argc) throw Error("--repo needs a directory (the repository's root)");
      given = argv[++i];
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  needs.insert(needs.begin(), "docs/bench");
  return findRepository(given, needs);
}

/// For a benchmark that takes no options but --repo (after repositoryFromArgs): throws
/// ddace::Error naming the first other argument (`ddace bench NAME ...` hands them on).
inline void noOtherOptions(int argc, char** argv, const std::string& name) {
  if (argc > 1) throw Error(name + " takes no options but --repo DIR (got '" + argv[1] + "')");
}

/// printf-style text, e.g. a row of a results table.
[[gnu::format(printf, 1, 2)]] inline std::string formatted(const char* format, ...) {
  va_list args, again;
  va_start(args, format);
  va_copy(again, args);
  std::string text(static_cast<size_t>(std::max(0, std::vsnprintf(nullptr, 0, format, args))), '\0');
  va_end(args);
  std::vsnprintf(text.data(), text.size() + 1, format, again);
  va_end(again);
  return text;
}

/// Writes `markdown` as docs/bench/<name>.md under `repo` and says where on stdout.
inline void writeResults(const std::filesystem::path& repo, const std::string& name, const std::string& markdown) {
  const std::filesystem::path out = repo / "docs" / "bench" / (name + ".md");
  writeTextFile(out.string(), markdown);
  std::cout << "wrote " << out.string() << "\n";
}

}  // namespace ddace::bench
