// SHA-256 (FIPS 180-4) of bytes, as the digests that bind a model directory's files
// together (docs/tgn.md, "The model directory"). Not for secrets: it detects edits and
// corruption, it authenticates nobody.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace ddace {

/// Incremental SHA-256: update() any number of times, then hex() or digest() once.
class Sha256 {
 public:
  Sha256();
  void update(std::string_view bytes);
  /// The 32-byte digest; the object may not be updated afterwards.
  std::array<std::uint8_t, 32> digest();
  /// The digest as 64 lower-case hexadecimal digits.
  std::string hex();

 private:
  void block(const std::uint8_t* p);
  std::array<std::uint32_t, 8> state_;
  std::array<std::uint8_t, 64> buffer_{};
  std::size_t buffered_ = 0;
  std::uint64_t length_ = 0;  ///< bytes so far
  bool finished_ = false;
};

/// SHA-256 of `bytes` as 64 lower-case hexadecimal digits.
std::string sha256Hex(std::string_view bytes);

/// True when `text` is 64 lower-case hexadecimal digits (a sha256Hex result).
bool isSha256Hex(std::string_view text);

}  // namespace ddace
