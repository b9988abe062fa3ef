// `ddace` — the command-line tool: generate, validate, train, eval, ... without a ROS master.
#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "command.h"
#include "ddace/common/error.h"

namespace {

void printHelp(std::ostream& out) {
  out << "usage: ddace <subcommand> [args]\n\nsubcommands:\n";
  for (const auto& [name, command] : ddace::cli::commands()) {
    out << "  " << command.usage << "\n      " << command.summary << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || (args.size() == 1 && (args[0] == "help" || args[0] == "--help" || args[0] == "-h"))) {
    printHelp(args.empty() ? std::cerr : std::cout);
    return args.empty() ? 2 : 0;
  }
  auto& commands = ddace::cli::commands();
  // `ddace help SUBCOMMAND` and `ddace SUBCOMMAND ... --help` (or -h, anywhere after the
  // subcommand: a user adds it to the line that failed): that subcommand's usage.
  const bool asked =
      (args.size() == 2 && args[0] == "help") ||
      std::any_of(args.begin() + 1, args.end(), [](const std::string& a) { return a == "--help" || a == "-h"; });
  const std::string name = asked && args[0] == "help" ? args[1] : args[0];
  auto it = commands.find(name);
  if (it == commands.end()) {
    std::cerr << "ddace: unknown subcommand '" << name << "'\n\n";
    printHelp(std::cerr);
    return 2;
  }
  if (asked) {
    std::cout << "usage: " << it->second.usage << "\n\n" << it->second.summary << "\n";
    return 0;
  }
  try {
    return it->second.run(std::vector<std::string>(args.begin() + 1, args.end()));
  } catch (const ddace::Error& e) {
    std::cerr << "ddace " << args[0] << ": error:\n" << e.what() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "ddace " << args[0] << ": error: " << e.what() << "\n";
  }
  return 1;
}
