// `ddace` — the command-line tool: generate, validate, train, eval, ... without a ROS master.
#include <iostream>

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
  if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
    printHelp(args.empty() ? std::cerr : std::cout);
    return args.empty() ? 2 : 0;
  }
  auto& commands = ddace::cli::commands();
  auto it = commands.find(args[0]);
  if (it == commands.end()) {
    std::cerr << "ddace: unknown subcommand '" << args[0] << "'\n\n";
    printHelp(std::cerr);
    return 2;
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
