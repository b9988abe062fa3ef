// The `ddace` tool's subcommands and their argument parsing.
//
// Each src/cli/cmd_<name>.cpp registers one subcommand with DDACE_COMMAND; main.cpp
// dispatches. Subcommands return the process exit code and report errors on stderr.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace ddace::cli {

/// Parsed `--flag value` options and positional arguments. Flags that take no value
/// are declared in `switches`. Unknown flags, missing values and bad numbers throw
/// ddace::Error naming the flag.
class Args {
 public:
  Args(const std::vector<std::string>& argv, const std::vector<std::string>& options,
       const std::vector<std::string>& switches = {});

  const std::vector<std::string>& positional() const { return positional_; }
  /// The i-th positional argument; throws naming `what` when it is missing.
  std::string positional(size_t i, const std::string& what) const;
  /// Throws when there are more than `n` positional arguments.
  void expectAtMostPositional(size_t n) const;

  bool has(const std::string& flag) const;
  std::string get(const std::string& flag, const std::string& fallback) const;
  std::string require(const std::string& flag) const;
  long getInt(const std::string& flag, long fallback) const;
  double getDouble(const std::string& flag, double fallback) const;

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

struct Command {
  std::string name;
  std::string usage;                                        ///< one line: "ddace generate FAMILY --out DIR [...]"
  std::string summary;                                      ///< one line for `ddace help`
  std::function<int(const std::vector<std::string>&)> run;  ///< args after the name
};

/// " (did you mean X?)" for the candidate closest to a mistyped `word` (a slip of one or two
/// letters, a swapped pair), "" when none is that close.
std::string didYouMean(const std::string& word, const std::vector<std::string>& candidates);

/// What to do about demonstrations of task directory `dir` that have no labelled step
/// (`all`: every one of them): validate's note and train's refusal say the same.
std::string unlabelledAdvice(const std::string& dir, bool all);

/// All registered subcommands, by name.
std::map<std::string, Command>& commands();

struct Registrar {
  explicit Registrar(Command command);
};

}  // namespace ddace::cli

#define DDACE_CLI_CONCAT2(a, b) a##b
#define DDACE_CLI_CONCAT(a, b) DDACE_CLI_CONCAT2(a, b)
/// DDACE_COMMAND({"name", "usage", "summary", function});
#define DDACE_COMMAND(...) \
  static ::ddace::cli::Registrar DDACE_CLI_CONCAT(ddace_command_, __LINE__)(::ddace::cli::Command __VA_ARGS__)
