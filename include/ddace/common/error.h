// Errors that name where they come from.
//
// Every reader in ddace reports problems as Diagnostics: a message plus the
// file, 1-based line and 1-based column it refers to (line/column 0 = unknown,
// e.g. "file does not exist"). A Diagnostic prints as `file:line:column: message`,
// the format compilers use, so editors can jump to it.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace ddace {

/// One problem in one place.
struct Diagnostic {
  std::string file;  ///< path as given by the caller; empty when not file-related
  int line = 0;      ///< 1-based line, 0 when unknown
  int column = 0;    ///< 1-based column (characters), 0 when unknown
  std::string message;

  /// `file:line:column: message` (parts that are unknown are left out).
  std::string str() const;
};

/// Thrown by every ddace reader and writer. Carries one or more Diagnostics;
/// what() lists them, one per line.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message);
  explicit Error(Diagnostic diagnostic);
  explicit Error(std::vector<Diagnostic> diagnostics);

  const std::vector<Diagnostic>& diagnostics() const { return diagnostics_; }

 private:
  std::vector<Diagnostic> diagnostics_;
};

/// Joins the str() of each diagnostic with newlines.
std::string formatDiagnostics(const std::vector<Diagnostic>& diagnostics);

}  // namespace ddace
