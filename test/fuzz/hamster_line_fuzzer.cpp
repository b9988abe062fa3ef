// libFuzzer target: the Hamster line parser must classify any byte stream, never crash.
// fuzz-modules: hamster
//
// The input is fed through the line assembler in two chunkings; every line is parsed,
// and data lines are decoded as both models. Invariants checked: a line that parses
// as Data re-encodes to exactly the same text (upper-cased), and the assembler never
// holds more than kMaxLineChars.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "ddace/hamster/protocol.h"

using namespace ddace::hamster;

namespace {

void check(std::string_view line) {
  const ParsedLine p = parseLine(line);
  if (p.kind == LineKind::Data) {
    std::string upper(line);
    std::transform(upper.begin(), upper.end(), upper.begin(), [](unsigned char c) { return std::toupper(c); });
    if (encodeLine(p.payload, p.address) != upper + "\r") std::abort();
    for (Model m : {Model::Hamster, Model::HamsterS}) {
      std::string why;
      if (auto s = decodeSensors(m, p.payload, &why)) {
        (void)encodeSensors(m, *s, s->has_light);
      } else if (why.empty()) {
        std::abort();  // a refusal must say why
      }
      (void)decodeEffector(m, p.payload, &why);
    }
  } else if (p.kind == LineKind::Malformed && p.error.empty()) {
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const char* text = reinterpret_cast<const char*>(data);
  LineAssembler whole, bytewise;
  size_t lines_whole = 0, lines_bytewise = 0;
  whole.push(text, size, [&](std::string_view l) {
    ++lines_whole;
    check(l);
  });
  for (size_t i = 0; i < size; ++i) bytewise.push(text + i, 1, [&](std::string_view) { ++lines_bytewise; });
  if (lines_whole != lines_bytewise || whole.pending() != bytewise.pending()) std::abort();
  if (whole.pending() > kMaxLineChars) std::abort();
  return 0;
}
