// SHA-256 against the FIPS 180-4 / NIST test vectors.
#include <gtest/gtest.h>

#include <string>

#include "ddace/common/sha256.h"

namespace {

TEST(Sha256, NistVectors) {
  EXPECT_EQ(ddace::sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(ddace::sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(ddace::sha256Hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(ddace::sha256Hex("abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopqklmnopqrl"
                             "mnopqrsmnopqrstnopqrstu"),
            "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
  EXPECT_EQ(ddace::sha256Hex(std::string(1000000, 'a')),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

TEST(Sha256, IncrementalEqualsWholeAcrossBlockBoundaries) {
  std::string text;
  for (int i = 0; i < 300; ++i) text += static_cast<char>(i * 7);
  for (size_t cut : {0, 1, 55, 56, 63, 64, 65, 128, 299}) {
    ddace::Sha256 h;
    h.update(std::string_view(text).substr(0, cut));
    h.update(std::string_view(text).substr(cut));
    EXPECT_EQ(h.hex(), ddace::sha256Hex(text)) << "cut at " << cut;
  }
}

TEST(Sha256, HexShape) {
  EXPECT_TRUE(ddace::isSha256Hex(ddace::sha256Hex("x")));
  EXPECT_FALSE(ddace::isSha256Hex("abc"));
  EXPECT_FALSE(ddace::isSha256Hex(std::string(64, 'G')));
  EXPECT_FALSE(ddace::isSha256Hex(std::string(64, 'A')));  // lower case only, as written
}

}  // namespace
