// What the ddace::Error of a refused input says, for tests: the one copy for every test
// binary of test/unit/.
#pragma once

#include <string>

#include "ddace/common/error.h"

namespace ddace::test {

/// The message of the ddace::Error `f` throws ("" when it throws none; any other
/// exception passes through and fails the test).
template <typename F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// Every diagnostic of the ddace::Error `f` throws, one "file:line:column: message" line
/// each ("" when it throws none).
template <typename F>
std::string diagnosticsOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    std::string all;
    for (const auto& d : e.diagnostics()) all += d.str() + "\n";
    return all;
  }
  return "";
}

/// The first of them, without the newline ("no error" when it throws none).
template <typename F>
std::string firstErrorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.diagnostics().empty() ? std::string(e.what()) : e.diagnostics().front().str();
  }
  return "no error";
}

}  // namespace ddace::test
