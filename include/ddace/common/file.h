// Reading whole files for the parsers (which then report their own line/column errors).
#pragma once

#include <string>

namespace ddace {

/// The bytes of `path`. Throws ddace::Error naming the file when it cannot be opened.
std::string readTextFile(const std::string& path);

}  // namespace ddace
