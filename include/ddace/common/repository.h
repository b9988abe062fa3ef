// Finding the ddace package directory at run time.
//
// Tools that read the repository's files (configs, test data, the Python references) or
// write its docs/ find it here instead of a path compiled into them, so a binary works
// from the workspace it was built in, from an install space and from a copy elsewhere.
// The package directory is the one whose package.xml has <name>ddace</name>. In order:
//   1. an explicit directory (a tool's --repo DIR),
//   2. the environment variable DDACE_REPO,
//   3. the current directory and its parents,
//   4. the running executable's directory and its parents (a workspace inside the
//      repository, the usual layout) and <parent>/share/ddace (an install space),
//   5. $ROS_PACKAGE_PATH (each entry and the packages up to two levels below it).
// A directory given explicitly (1, 2) must be a ddace package holding what the caller
// needs, else it is an error (not silently replaced by another); found ones (3-5) that
// lack something the caller needs are skipped (an install space has config/ but no
// docs/). A package.xml reached through a symlink (the workspace's symlink farm, see
// scripts/setup) resolves to the directory it lives in: the repository itself.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace ddace {

/// The environment variable that names the package directory (step 2).
constexpr const char* kRepositoryEnv = "DDACE_REPO";

/// Every input of the search, so it can be run on any directory tree.
struct RepositorySearch {
  std::string explicit_dir;              ///< step 1 ("" = not given), e.g. --repo DIR
  std::string explicit_what = "--repo";  ///< how the caller names step 1 in messages
  std::string env_dir;                   ///< the value of DDACE_REPO ("" = unset)
  std::vector<std::string> walk_from;    ///< steps 3-4: directories whose parents are searched, in order
  std::string ros_package_path;          ///< step 5: colon-separated directories
  std::vector<std::string> needs;        ///< paths relative to the package the caller uses, e.g. "docs/bench"
};

/// True when `dir`/package.xml is a readable package manifest whose <name> is ddace.
bool isDdacePackage(const std::filesystem::path& dir);

/// The package directory `search` finds (absolute, symlinks resolved). Throws
/// ddace::Error naming every place it looked and how to point it at one (--repo DIR,
/// DDACE_REPO) when none is found, or naming the explicit directory and what it lacks.
std::filesystem::path locateRepository(const RepositorySearch& search);

/// locateRepository for this process: `explicit_dir` (a --repo value, "" when not
/// given), $DDACE_REPO, the current directory, this executable (/proc/self/exe) and
/// $ROS_PACKAGE_PATH.
std::filesystem::path findRepository(const std::string& explicit_dir = "", const std::vector<std::string>& needs = {});

}  // namespace ddace
