// The front end's side of ddace_learn: the subcommands built into ddace_learn (they load
// libtorch) are registered here from the table that `ddace_learn --describe` wrote at
// build time, and run by executing ddace_learn next to this program.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "command.h"
#include "ddace/common/error.h"

namespace ddace::cli {
namespace {

struct LearnCommand {
  const char* name;
  const char* usage;
  const char* summary;
};

// Generated (CMakeLists.txt): const LearnCommand kLearnCommands[] = {{"train", R"..."}, ...};
#include "learn_commands.inc"

/// Replaces this process with `ddace_learn NAME ARGS...` (exit status, output and signals are its own).
int runLearn(const std::string& name, const std::vector<std::string>& args) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("cannot find this program (/proc/self/exe): " + ec.message());
  const std::string learn = (self.parent_path() / "ddace_learn").string();
  std::vector<std::string> words = {learn, name};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  ::execv(learn.c_str(), argv.data());
  throw Error("cannot run " + learn + " (ddace " + name + " is built into it): " + std::strerror(errno));
}

[[maybe_unused]] const bool registered = [] {
  for (const auto& c : kLearnCommands)
    commands()[c.name] = Command{c.name, c.usage, c.summary,
                                 [name = std::string(c.name)](const auto& args) { return runLearn(name, args); }};
  return true;
}();

}  // namespace
}  // namespace ddace::cli
