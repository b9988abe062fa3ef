// The common YAML checker: diagnostics at file:line:column, one per problem.
#include <gtest/gtest.h>

#include "ddace/common/yaml_checker.h"

using ddace::Diagnostic;
using ddace::YamlChecker;

TEST(YamlChecker, UnknownKeysNameTheirPlaceAndTheAllowedOnes) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("width: 3\nspeed: 2\ncolour: red\n");
  ASSERT_TRUE(root.IsMap());
  c.onlyKeys(root, {"width", "height"}, "the test config");
  ASSERT_EQ(c.errors().size(), 2u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:2:1: unknown key 'speed' in the test config (allowed: height, width)");
  EXPECT_EQ(c.errors()[1].str(), "c.yaml:3:1: unknown key 'colour' in the test config (allowed: height, width)");
  try {
    c.throwIfErrors();
    FAIL() << "throwIfErrors did not throw";
  } catch (const ddace::Error& e) {
    EXPECT_EQ(e.diagnostics().size(), 2u);
    EXPECT_EQ(std::string(e.what()), c.errors()[0].str() + "\n" + c.errors()[1].str());
  }
}

TEST(YamlChecker, NoErrorsNoThrow) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: 1.5\nb: true\nc: text\n");
  c.onlyKeys(root, {"a", "b", "c"}, "x");
  double a = 0;
  bool b = false;
  std::string s;
  EXPECT_TRUE(c.positive(root["a"], "a", a));
  EXPECT_TRUE(c.boolean(root["b"], "b", b));
  EXPECT_TRUE(c.scalar(root["c"], "c", s));
  EXPECT_DOUBLE_EQ(a, 1.5);
  EXPECT_TRUE(b);
  EXPECT_EQ(s, "text");
  EXPECT_TRUE(c.errors().empty());
  EXPECT_NO_THROW(c.throwIfErrors());
}

TEST(YamlChecker, NonScalarIsNotASingleValue) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("name: [a, b]\n");
  std::string out = "kept";
  EXPECT_FALSE(c.scalar(root["name"], "name", out));
  EXPECT_EQ(out, "kept");
  ASSERT_EQ(c.errors().size(), 1u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:1:7: name must be a single value");
}

TEST(YamlChecker, TextIsPrintableUtf8) {
  YamlChecker c("c.yaml");
  // Accepted: ASCII, two-, three- and four-byte UTF-8. Refused: a lone continuation byte
  // (a name the YAML writer would write back as U+FFFD), an overlong form, a truncated
  // sequence, a C0 and a C1 control character.
  const YAML::Node root = c.parse(
      "a: plain\nb: \"caf\xc3\xa9 \xe2\x86\x92 \xf0\x9f\xa4\x96\"\n"
      "c: \"ta\x98s\"\nd: \"\xc0\xaf\"\ne: \"x\xe2\x86\"\nf: \"a\x02"
      "b\"\ng: \"a\xc2\x85"
      "b\"\n");
  std::string out = "kept";
  EXPECT_TRUE(c.text(root["a"], "a", out));
  EXPECT_EQ(out, "plain");
  EXPECT_TRUE(c.text(root["b"], "b", out));
  EXPECT_EQ(out, "caf\xc3\xa9 \xe2\x86\x92 \xf0\x9f\xa4\x96");
  out = "kept";
  for (const char* key : {"c", "d", "e", "f", "g"}) EXPECT_FALSE(c.text(root[key], key, out)) << key;
  EXPECT_EQ(out, "kept");
  ASSERT_EQ(c.errors().size(), 5u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:3:4: c must be printable UTF-8 text (not UTF-8 at byte 3)");
  EXPECT_NE(c.errors()[3].str().find("control character at byte 2"), std::string::npos) << c.errors()[3].str();
  EXPECT_NE(c.errors()[4].str().find("control character at byte 2"), std::string::npos) << c.errors()[4].str();
}

TEST(YamlChecker, NumbersMustBeFinite) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: inf\nb: nan\nc: 1.5m\nd: -2\n");
  double out = 7;
  EXPECT_FALSE(c.number(root["a"], "a", out));
  EXPECT_FALSE(c.number(root["b"], "b", out));
  EXPECT_FALSE(c.number(root["c"], "c", out));
  EXPECT_EQ(out, 7);
  EXPECT_TRUE(c.number(root["d"], "d", out));
  EXPECT_EQ(out, -2);
  EXPECT_FALSE(c.positive(root["d"], "d", out));
  ASSERT_EQ(c.errors().size(), 4u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:1:4: a: 'inf' is not a finite number");
  EXPECT_EQ(c.errors()[1].str(), "c.yaml:2:4: b: 'nan' is not a finite number");
  EXPECT_EQ(c.errors()[2].str(), "c.yaml:3:4: c: '1.5m' is not a finite number");
  EXPECT_EQ(c.errors()[3].str(), "c.yaml:4:4: d must be > 0 (got -2)");
}

TEST(YamlChecker, IntegersAreWholeAndInRangeNeverTruncated) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: 12\nb: 2.5\nc: 0\nd: 1e30\ne: many\nf: 1e2\n");
  int a = -1, b = -1, cc = -1, d = -1, e = -1, f = -1;
  EXPECT_TRUE(c.integer(root["a"], "a", 1, 100, a));
  EXPECT_FALSE(c.integer(root["b"], "b", 1, 100, b));
  EXPECT_FALSE(c.integer(root["c"], "c", 1, 100, cc));
  EXPECT_FALSE(c.integer(root["d"], "d", 1, 100, d));  // far beyond int: refused, not overflowed
  EXPECT_FALSE(c.integer(root["e"], "e", 1, 100, e));
  EXPECT_TRUE(c.integer(root["f"], "f", 1, 100, f));
  EXPECT_EQ(a, 12);
  EXPECT_EQ(f, 100);
  EXPECT_EQ(b, -1);  // untouched on failure
  EXPECT_EQ(cc, -1);
  EXPECT_EQ(d, -1);
  ASSERT_EQ(c.errors().size(), 4u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:2:4: b must be an integer in 1..100 (got 2.5)");
  EXPECT_EQ(c.errors()[1].str(), "c.yaml:3:4: c must be an integer in 1..100 (got 0)");
  EXPECT_EQ(c.errors()[2].str(), "c.yaml:4:4: d must be an integer in 1..100 (got 1e30)");
  EXPECT_EQ(c.errors()[3].str(), "c.yaml:5:4: e: 'many' is not a finite number");
}

TEST(YamlChecker, NumbersInARangeSayTheRangeAndTheValue) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: 0.5\nb: 1.25\nc: -0.001\nd: 1e-3\ne: wide\n");
  double a = -1, b = -1, cc = -1, d = -1, e = -1;
  EXPECT_TRUE(c.number(root["a"], "a", 0.0, 1.0, a));
  EXPECT_FALSE(c.number(root["b"], "b", 0.0, 1.0, b));
  EXPECT_FALSE(c.number(root["c"], "c", 0.0, 1.0, cc));
  EXPECT_TRUE(c.number(root["d"], "d", 1e-3, 1.0, d));  // the bounds belong to the range
  EXPECT_FALSE(c.number(root["e"], "e", 0.0, 1.0, e));
  EXPECT_EQ(a, 0.5);
  EXPECT_EQ(d, 1e-3);
  EXPECT_EQ(b, -1);  // untouched on failure
  EXPECT_EQ(cc, -1);
  ASSERT_EQ(c.errors().size(), 3u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:2:4: b must be in 0..1 (got 1.25)");
  EXPECT_EQ(c.errors()[1].str(), "c.yaml:3:4: c must be in 0..1 (got -0.001)");
  EXPECT_EQ(c.errors()[2].str(), "c.yaml:5:4: e: 'wide' is not a finite number");
}

TEST(YamlChecker, ARequiredKeyNeedsAValue) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: 1\nb:\nc: ~\n");
  EXPECT_EQ(c.required(root, "a").Scalar(), "1");
  EXPECT_FALSE(c.required(root, "b", "the test: "));  // a key without a value ...
  EXPECT_FALSE(c.required(root, "c"));                // ... or with a null one has none
  EXPECT_FALSE(c.required(root, "d"));
  EXPECT_FALSE(c.required(root["a"], "x"));  // not a mapping: for expectMap to say
  ASSERT_EQ(c.errors().size(), 3u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:1:1: the test: missing key 'b'");
  EXPECT_EQ(c.errors()[1].str(), "c.yaml:1:1: missing key 'c'");
  EXPECT_EQ(c.errors()[2].str(), "c.yaml:1:1: missing key 'd'");
}

TEST(YamlChecker, BooleansAreTrueOrFalse) {
  YamlChecker c("c.yaml");
  const YAML::Node root = c.parse("a: True\nb: false\nc: yes\n");
  bool a = false, b = true, x = true;
  EXPECT_TRUE(c.boolean(root["a"], "a", a));
  EXPECT_TRUE(c.boolean(root["b"], "b", b));
  EXPECT_FALSE(c.boolean(root["c"], "c", x));
  EXPECT_TRUE(a);
  EXPECT_FALSE(b);
  EXPECT_TRUE(x);
  ASSERT_EQ(c.errors().size(), 1u);
  EXPECT_EQ(c.errors()[0].str(), "c.yaml:3:4: c: 'yes' is not true or false");
}

TEST(YamlChecker, SyntaxErrorsAndMappings) {
  YamlChecker c("c.yaml");
  EXPECT_FALSE(c.parse("a: [1, 2\n").IsDefined());
  ASSERT_EQ(c.errors().size(), 1u);
  EXPECT_EQ(c.errors()[0].file, "c.yaml");
  EXPECT_GT(c.errors()[0].line, 0);
  EXPECT_NE(c.errors()[0].message.find("YAML syntax error: "), std::string::npos);

  YamlChecker m("m.yaml");
  EXPECT_FALSE(m.expectMap(m.parse("- 1\n- 2\n"), "the list"));
  EXPECT_TRUE(m.expectMap(m.parse("a: 1\n"), "the map"));
  ASSERT_EQ(m.errors().size(), 1u);
  EXPECT_EQ(m.errors()[0].str(), "m.yaml:1:1: the list must be a mapping (key: value)");
}
