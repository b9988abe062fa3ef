// Numbers in the task files: written so they read back exactly, read only when the whole
// field is a number.
#pragma once

#include <string>
#include <string_view>

namespace ddace::task::detail {

/// The shortest text that reads back as exactly `v` (std::to_chars), e.g. "0.03", "1e-07".
std::string shortestNumber(double v);
/// `v` with six decimals ("0.123457") when that reads back as exactly `v` -- the
/// micrometre and 20 Hz values the generators and the recorder produce -- else
/// shortestNumber(v), so every finite value survives a write and a read.
std::string csvNumber(double v);
/// True, with `out`, when the whole of `text` is a finite number (strtod syntax: no
/// leading or trailing bytes, no embedded NUL).
bool parseFiniteNumber(std::string_view text, double& out);

}  // namespace ddace::task::detail
