// TOML reading (server/app/toml_file): typed reads with fallbacks, and errors that name the
// file, the line and the dotted key (support/config_files.hpp).
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "app/toml_file.hpp"
#include "support/config_files.hpp"

namespace {

using hapticloth::app::TomlFile;
using namespace hapticloth::test;

const std::string kText =
    "n = 1.5\n"        // 1
    "i = 3\n"          // 2
    "b = true\n"       // 3
    "s = \"x\"\n"      // 4
    "nan = nan\n"      // 5
    "[t]\n"            // 6
    "xs = [1, 2]\n"    // 7
    "ss = [\"a\", 1]\n";  // 8

TEST(TomlFile, TypedReadsAndFallbacks) {
  const TomlFile f = TomlFile::parse(kText, "t.toml");
  const toml::table& r = f.root();
  EXPECT_EQ(f.path(), "t.toml");
  EXPECT_DOUBLE_EQ(f.number(r, "", "n"), 1.5);
  EXPECT_DOUBLE_EQ(f.number(r, "", "i"), 3.0);  // an integer is a number too
  EXPECT_EQ(f.integer(r, "", "i", std::nullopt, 0, 10), 3);
  EXPECT_TRUE(f.boolean(r, "", "b"));
  EXPECT_EQ(f.string(r, "", "s"), "x");
  EXPECT_DOUBLE_EQ(f.number(r, "", "absent", 2.0), 2.0);
  EXPECT_EQ(f.integer(r, "", "absent", 7, 0, 10), 7);
  EXPECT_DOUBLE_EQ(f.number_in(r, "", "n", std::nullopt, 1.0, 2.0, "m"), 1.5);
  EXPECT_FALSE(f.boolean(r, "", "absent", false));
  EXPECT_EQ(f.string(r, "", "absent", std::string("d")), "d");
  const toml::table* t = f.table(r, "", "t", true);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(f.numbers(*t, "t", "xs", 1, 2), (std::vector<double>{1.0, 2.0}));
  EXPECT_TRUE(f.strings(*t, "t", "absent").empty());
  EXPECT_EQ(f.table(r, "", "absent", false), nullptr);
  EXPECT_NO_THROW(f.only_keys(*t, "t", {"xs", "ss"}));
}

TEST(TomlFile, BadValuesNameTheLineAndKey) {
  const TomlFile f = TomlFile::parse(kText, "t.toml");
  const toml::table& r = f.root();
  const toml::table& t = *f.table(r, "", "t", true);
  const TomlFile g = TomlFile::parse("big = 4294967297\n", "t.toml");  // 2^32 + 1: an int would wrap to 1
  struct Case {
    const char* name;
    std::function<void()> read;
    std::vector<std::string> parts;
  };
  const std::vector<Case> cases = {
      {"NumberOfAString", [&] { f.number(r, "", "s"); }, {at_line(4), "key 's'", "expected a number"}},
      {"NumberNotFinite", [&] { f.number(r, "", "nan"); }, {at_line(5), "key 'nan'", "must be finite"}},
      {"IntegerOfAFloat", [&] { f.integer(r, "", "n", std::nullopt, 0, 10); }, {at_line(1), "key 'n'", "expected an integer"}},
      {"IntegerOutOfRange", [&] { f.integer(r, "", "i", std::nullopt, 4, 10); },
       {at_line(2), "key 'i'", "must be an integer in [4, 10], not 3"}},
      {"IntegerPast2To32", [&] { g.integer(g.root(), "", "big", std::nullopt, 1, 100000); },
       {"key 'big'", "must be an integer in [1, 100000], not 4294967297"}},
      {"NumberOutOfRange", [&] { f.number_in(r, "", "n", std::nullopt, 0.0, 1.0, "m"); },
       {at_line(1), "key 'n'", "must be >= 0 and <= 1 m, not 1.5"}},
      {"NumberAtAnOpenEnd", [&] { f.number_in(r, "", "n", std::nullopt, 1.5, 2.0, "s", true); },
       {at_line(1), "key 'n'", "must be > 1.5 and <= 2 s"}},
      {"BooleanOfAnInteger", [&] { f.boolean(r, "", "i"); }, {at_line(2), "key 'i'", "expected true or false"}},
      {"StringOfABoolean", [&] { f.string(r, "", "b"); }, {at_line(3), "key 'b'", "expected a string"}},
      {"MissingNumber", [&] { f.number(t, "t", "absent"); },
       {at_line(6), "key 't.absent'", "missing (a number is required)"}},
      {"MissingInteger", [&] { f.integer(t, "t", "absent", std::nullopt, 0, 1); }, {"key 't.absent'", "missing (an integer is required)"}},
      {"MissingBoolean", [&] { f.boolean(t, "t", "absent"); }, {"key 't.absent'", "missing (true or false is required)"}},
      {"MissingString", [&] { f.string(t, "t", "absent"); }, {"key 't.absent'", "missing (a string is required)"}},
      {"NumbersTooShort", [&] { f.numbers(t, "t", "xs", 3, 3); }, {at_line(7), "key 't.xs'", "expected 3 numbers, got 2"}},
      {"StringsWithANumber", [&] { f.strings(t, "t", "ss"); }, {at_line(8), "key 't.ss[1]'", "expected a string"}},
      {"MissingTable", [&] { f.table(r, "", "absent", true); }, {"key 'absent'", "a table [absent] is required"}},
      {"UnknownKey", [&] { f.only_keys(r, "", {"n", "b", "s", "nan", "t"}); },
       {at_line(2), "key 'i'", "unknown key (allowed here: n, b, s, nan, t)"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<std::string> parts = {"t.toml"};
    parts.insert(parts.end(), c.parts.begin(), c.parts.end());
    expect_config_error(c.read, parts);
  }
}

TEST(TomlFile, InvalidTomlNamesTheLine) {
  expect_config_error([] { TomlFile::parse("a = 1\nb = = 2\n", "bad.toml"); },
                      {"bad.toml" + at_line(2), "invalid TOML"});
}

TEST(TomlFile, MissingFile) {
  expect_config_error([] { TomlFile::load("/nonexistent/hapticloth.toml"); },
                      {"/nonexistent/hapticloth.toml", "cannot open"});
}

}  // namespace
