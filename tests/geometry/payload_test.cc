// Tests of geometry/payload.h: the [Kang] floor-code format "0/x/y", a [Bach]-style
// identifier plus coordinates, malformed and hostile payloads, and spec validation.
#include "geometry/payload.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

namespace waymark {
namespace {

using ::testing::HasSubstr;

// [Kang] (Drones 2024, 8(4), 130): "0/2/10" = floor code (kind 0) at x = 2, y = 10.
PayloadSpec Seed004Spec() { return {"^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", {"kind", "x", "y"}}; }

// [Bach] (Bach et al.): wall codes carrying an identifier and their global coordinates;
// here written "ID=W07;X=12.5;Y=-3.25;Z=1.2;YAW=90" with optional Z and YAW.
PayloadSpec Seed000Spec() {
  return {"^ID=([A-Za-z0-9_-]+);X=([^;]*);Y=([^;]*)(?:;Z=([^;]*))?(?:;YAW=([^;]*))?$",
          {"id", "x", "y", "z", "yaw_deg"}};
}

TEST(PayloadTest, Seed004FloorCode) {
  const PayloadParser parser(Seed004Spec());
  std::string why = "stale";
  const std::optional<PayloadData> data = parser.Parse("0/2/10", &why);
  ASSERT_TRUE(data.has_value()) << why;
  EXPECT_EQ(why, "");
  EXPECT_TRUE(data->HasPosition());
  EXPECT_DOUBLE_EQ(*data->x_m, 2.0);
  EXPECT_DOUBLE_EQ(*data->y_m, 10.0);
  EXPECT_FALSE(data->z_m.has_value());
  EXPECT_FALSE(data->yaw_rad.has_value());
  EXPECT_EQ(data->attributes, (std::map<std::string, std::string>{{"kind", "0"}}));
  const std::optional<PayloadData> negative = parser.Parse("1/-0.5/3.25");
  ASSERT_TRUE(negative.has_value());
  EXPECT_DOUBLE_EQ(*negative->x_m, -0.5);
  EXPECT_DOUBLE_EQ(*negative->y_m, 3.25);
  EXPECT_EQ(negative->attributes.at("kind"), "1");
}

TEST(PayloadTest, DefaultHeightFillsAMissingZOnly) {
  PayloadSpec floor = Seed004Spec();
  floor.default_z_m = 0.0;  // [Kang]'s floor codes lie on the floor
  const std::optional<PayloadData> data = PayloadParser(floor).Parse("0/2/10");
  ASSERT_TRUE(data.has_value());
  ASSERT_TRUE(data->z_m.has_value());
  EXPECT_DOUBLE_EQ(*data->z_m, 0.0);
  // A printed z wins over the default; a text without coordinates gets none.
  PayloadSpec wall = Seed000Spec();
  wall.default_z_m = 0.3;
  const PayloadParser parser(wall);
  EXPECT_DOUBLE_EQ(*parser.Parse("ID=W07;X=1;Y=2;Z=1.2")->z_m, 1.2);
  EXPECT_DOUBLE_EQ(*parser.Parse("ID=W07;X=1;Y=2")->z_m, 0.3);
  EXPECT_FALSE(parser.Parse("unrelated text").has_value());
  // A default height needs x and y, and must be finite.
  PayloadSpec no_xy{"^(\\w+)$", {"name"}, 0.0};
  EXPECT_THROW(ValidatePayloadSpec(no_xy), std::runtime_error);
  floor.default_z_m = std::nan("");
  EXPECT_THROW(ValidatePayloadSpec(floor), std::runtime_error);
}

TEST(PayloadTest, Seed000IdentifierAndCoordinates) {
  const PayloadParser parser(Seed000Spec());
  const std::optional<PayloadData> full = parser.Parse("ID=W07;X=12.5;Y=-3.25;Z=1.2;YAW=270");
  ASSERT_TRUE(full.has_value());
  EXPECT_DOUBLE_EQ(*full->x_m, 12.5);
  EXPECT_DOUBLE_EQ(*full->y_m, -3.25);
  EXPECT_DOUBLE_EQ(*full->z_m, 1.2);
  EXPECT_NEAR(*full->yaw_rad, -M_PI / 2.0, 1e-15);  // 270 deg wraps to -90 deg
  EXPECT_EQ(full->attributes, (std::map<std::string, std::string>{{"id", "W07"}}));
  // Optional groups that do not take part leave their coordinate absent.
  const std::optional<PayloadData> planar = parser.Parse("ID=A1;X=1;Y=2");
  ASSERT_TRUE(planar.has_value());
  EXPECT_FALSE(planar->z_m.has_value());
  EXPECT_FALSE(planar->yaw_rad.has_value());
  const std::optional<PayloadData> exponent = parser.Parse("ID=A1;X=+1e-2;Y=2E1;YAW=-180");
  ASSERT_TRUE(exponent.has_value());
  EXPECT_DOUBLE_EQ(*exponent->x_m, 0.01);
  EXPECT_DOUBLE_EQ(*exponent->y_m, 20.0);
  EXPECT_NEAR(*exponent->yaw_rad, M_PI, 1e-15);  // (-pi, pi]
}

TEST(PayloadTest, NonMatchingTextIsAnOrdinaryCode) {
  const PayloadParser parser(Seed004Spec());
  for (const std::string text : {"", "hello", "0/2", "0/2/10/4", "a/2/10", " 0/2/10", "0/2/10\n"}) {
    std::string why = "stale";
    EXPECT_FALSE(parser.Parse(text, &why).has_value()) << text;
    EXPECT_EQ(why, "") << text;
  }
}

TEST(PayloadTest, MatchingTextWithBadCoordinatesIsRejectedWithAReason) {
  const PayloadParser seed004(Seed004Spec());
  // The pattern allows "1.2.3", "." and "-": they match but are not numbers.
  for (const std::string text : {"0/1.2.3/4", "0/./4", "0/-./4", "0/4/1..5"}) {
    std::string why;
    EXPECT_FALSE(seed004.Parse(text, &why).has_value()) << text;
    EXPECT_THAT(why, HasSubstr("not a finite number")) << text;
  }
  const PayloadParser seed000(Seed000Spec());
  for (const std::string text :
       {"ID=A;X=nan;Y=1", "ID=A;X=inf;Y=1", "ID=A;X=1e999;Y=1", "ID=A;X=;Y=1", "ID=A;X= 1;Y=1",
        "ID=A;X=0x10;Y=1", "ID=A;X=1;Y=2;Z=up", "ID=A;X=1;Y=2;YAW=north", "ID=A;X=++1;Y=1"}) {
    std::string why;
    EXPECT_FALSE(seed000.Parse(text, &why).has_value()) << text;
    EXPECT_THAT(why, HasSubstr("not a finite number")) << text;
  }
  std::string why;
  EXPECT_FALSE(seed000.Parse("ID=A;X=1;Y=2;YAW=north", &why).has_value());
  EXPECT_THAT(why, HasSubstr("yaw_deg"));
}

TEST(PayloadTest, MissingRequiredGroupIsRejected) {
  const PayloadParser parser({"^P(?:x(\\d+))?y(\\d+)$", {"x", "y"}});
  std::string why;
  EXPECT_FALSE(parser.Parse("Py5", &why).has_value());
  EXPECT_THAT(why, HasSubstr("`x` is missing"));
  EXPECT_TRUE(parser.Parse("Px3y5").has_value());
}

TEST(PayloadTest, HugeAndBinaryInputsNeverThrow) {
  const PayloadParser parser({"^(.*)/(.*)/(.*)$", {"kind", "x", "y"}});
  // 1 MB would overflow libstdc++'s recursive matcher; it is refused before matching.
  std::string huge(1 << 20, '7');
  huge[1000] = '/';
  huge[2000] = '/';
  std::string why;
  EXPECT_FALSE(parser.Parse(huge, &why).has_value());
  EXPECT_THAT(why, HasSubstr("longer than 1024"));
  // The longest accepted text still matches (and does not exhaust the stack).
  const std::string longest = std::string(kMaxPayloadBytes - 8, 'k') + "/-1.5/22";
  ASSERT_EQ(longest.size(), kMaxPayloadBytes);
  const std::optional<PayloadData> data = parser.Parse(longest, &why);
  ASSERT_TRUE(data.has_value()) << why;
  EXPECT_EQ(data->attributes.at("kind"), std::string(kMaxPayloadBytes - 8, 'k'));
  EXPECT_DOUBLE_EQ(*data->x_m, -1.5);
  EXPECT_DOUBLE_EQ(*data->y_m, 22.0);
  EXPECT_FALSE(parser.Parse(longest + "2", &why).has_value());  // one byte more
  EXPECT_THAT(why, HasSubstr("longer than"));
  // A huge number of digits still parses or is refused, never throws.
  std::string digits = "0/" + std::string(900, '9') + "/1";
  EXPECT_NO_THROW(parser.Parse(digits, &why));
  EXPECT_THAT(why, HasSubstr("not a finite number"));  // 1e900 overflows double
  // Binary bytes, NUL included.
  const std::string binary("0/\0\xff\xfe/1", 7);
  EXPECT_NO_THROW(parser.Parse(binary, &why));
  EXPECT_FALSE(parser.Parse(binary).has_value());
}

TEST(PayloadTest, InvalidSpecsThrowClearErrors) {
  const auto expect_error = [](const PayloadSpec& spec, const std::string& text) {
    try {
      PayloadParser parser(spec);
      ADD_FAILURE() << "expected an error containing `" << text << "`";
    } catch (const std::runtime_error& e) {
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
    EXPECT_THROW(ValidatePayloadSpec(spec), std::runtime_error);
  };
  expect_error({"^(\\d+/(.*)$", {"kind", "x"}}, "invalid regular expression");
  expect_error({"^(\\d+)/(.*)$", {"kind", "x", "y"}}, "expected 2 names");
  expect_error({"^(\\d+)/(.*)/(.*)$", {"kind", "x"}}, "expected 3 names");
  expect_error({"^(\\d+)/(.*)$", {"", "x"}}, "non-empty");
  expect_error({"^(.*)/(.*)$", {"x", "x"}}, "appears twice");
  expect_error({"^(.*)/(.*)$", {"id", "x"}}, "`x` needs both `x` and `y`");
  expect_error({"^(.*)/(.*)$", {"id", "z"}}, "`z` needs both");
  // RE2 syntax: no back-references or look-arounds; repetition counts up to 1000. (std::regex's
  // compiler overflowed an int on a huge count, found by fuzz/payload_fuzz.cc.)
  expect_error({"^(a)\\1$", {"id"}}, "invalid regular expression");
  expect_error({"^(?=a)(a)$", {"id"}}, "invalid regular expression");
  // A count too large to read is no repetition at all: the braces are literal (as in Perl).
  const PayloadParser huge_count({"^(a{77777777777777777777})$", {"id"}});
  ASSERT_TRUE(huge_count.Parse("a{77777777777777777777}").has_value());
  EXPECT_FALSE(huge_count.Parse("aaaa").has_value());
  expect_error({"^(a{1001})$", {"id"}}, "invalid regular expression");
  EXPECT_NO_THROW(ValidatePayloadSpec({"^(\\d{1,6})/(x{12})$", {"a", "b"}}));
  EXPECT_NO_THROW(ValidatePayloadSpec({"^([a+]+)$", {"id"}}));  // '+' in a class is a character
  // Non-capturing groups do not count; a spec without coordinates is valid.
  EXPECT_NO_THROW(ValidatePayloadSpec({"^(?:L|R)-(\\d+)$", {"shelf"}}));
  const PayloadParser attributes_only({"^(?:L|R)-(\\d+)$", {"shelf"}});
  const std::optional<PayloadData> data = attributes_only.Parse("L-12");
  ASSERT_TRUE(data.has_value());
  EXPECT_FALSE(data->HasPosition());
  EXPECT_EQ(data->attributes.at("shelf"), "12");
}

// Issue 18: payload text comes from anyone who prints a code. Patterns on which a backtracking
// engine (std::regex, used before) takes exponential time -- nested repetitions, overlapping
// alternatives under one repetition -- are valid and match a hostile text of the longest
// accepted length in far less than a second.
TEST(PayloadTest, MatchingTimeIsLinearInTheTextForEveryPattern) {
  const std::vector<PayloadSpec> specs = {{"^(a+)+$", {"g1"}},
                                          {"^(?:a|a)*(b)$", {"g1"}},
                                          {"^((a*)*)*(b)$", {"g1", "g2", "g3"}},
                                          {"^(a|aa)+(b)$", {"g1", "g2"}},
                                          {"X=([^;]*)+Y=(.*)", {"g1", "g2"}}};
  const std::string hostile = std::string(kMaxPayloadBytes - 1, 'a') + "!";
  const auto start = std::chrono::steady_clock::now();
  for (const PayloadSpec& spec : specs) {
    SCOPED_TRACE(spec.pattern);
    const PayloadParser parser(spec);
    std::string why = "unset";
    EXPECT_FALSE(parser.Parse(hostile, &why).has_value());
    EXPECT_EQ(why, "");  // an ordinary non-matching text
  }
  // std::regex needs about 2^1000 steps for the first pattern alone; RE2 a few microseconds each.
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  // The nested pattern of the fuzzing finding still captures as written.
  const PayloadParser nested({"^ID=(\\w+);X=([^;]*)+;Y=(.*)$", {"id", "x", "y"}});
  const std::optional<PayloadData> data = nested.Parse("ID=A7;X=1.5;Y=-2");
  ASSERT_TRUE(data.has_value());
  EXPECT_DOUBLE_EQ(*data->x_m, 1.5);
  EXPECT_DOUBLE_EQ(*data->y_m, -2.0);
  EXPECT_EQ(data->attributes.at("id"), "A7");
}

}  // namespace
}  // namespace waymark
