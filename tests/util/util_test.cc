// Tests of util/: the one number formatter, the options-check helper and the order statistics.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "util/check.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark {
namespace {

TEST(FormatTest, DoubleRoundTripsAndFixedAndSignificant) {
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(1e-9), "1e-09");
  EXPECT_EQ(FormatDouble(12345.0), "12345");
  EXPECT_EQ(FormatDouble(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(FormatDouble(-std::numeric_limits<double>::infinity()), "-inf");
  const double third = 1.0 / 3.0;
  EXPECT_EQ(std::stod(FormatDouble(third)), third);
  EXPECT_EQ(FormatFixed(3.14159, 2), "3.14");
  EXPECT_EQ(FormatFixed(-0.5, 0), "-0");
  EXPECT_EQ(FormatFixed(1e308, 1).size(), 311u);  // 309 digits, the point and one decimal
  EXPECT_EQ(FormatSignificant(0.1 + 0.2, 6), "0.3");
  EXPECT_EQ(FormatSignificant(123456789.0, 4), "1.235e+08");
}

struct Options {
  double rate_hz = 10.0;
  int frames = 1;
  Options* nested = nullptr;
  bool Check(std::string* why) const {
    WAYMARK_CHECK_OPTION(IsFinitePositive(rate_hz), "rate_hz must be finite and > 0");
    WAYMARK_CHECK_OPTION(frames >= 1, "frames must be >= " + std::to_string(1));
    WAYMARK_CHECK_OPTION(nested == nullptr || nested->Check(why), nullptr);
    return true;
  }
};

TEST(CheckTest, OneLinePerRuleNullSafeAndNestedMessagesKept) {
  Options options;
  std::string why = "untouched";
  EXPECT_TRUE(options.Check(&why));
  EXPECT_EQ(why, "untouched");
  options.rate_hz = std::nan("");
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "rate_hz must be finite and > 0");
  EXPECT_FALSE(options.Check(nullptr));  // the verdict alone
  options.rate_hz = 1.0;
  options.frames = 0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "frames must be >= 1");
  Options inner;
  inner.rate_hz = -1.0;
  options.frames = 3;
  options.nested = &inner;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "rate_hz must be finite and > 0");  // the nested rule's own message
  EXPECT_FALSE(options.Check(nullptr));
  EXPECT_TRUE(IsFiniteInRange(0.5, 0.0, 1.0));
  EXPECT_FALSE(IsFiniteInRange(std::numeric_limits<double>::infinity(), 0.0, 1e308));
  EXPECT_FALSE(IsFiniteAtLeast(std::nan(""), 0.0));
}

TEST(StatsTest, MedianAndQuantilesInterpolateLikeNumpy) {
  EXPECT_DOUBLE_EQ(Median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_DOUBLE_EQ(Median({4.0, 1.0, 3.0, 2.0}), 2.5);  // mean of the two middle values
  EXPECT_DOUBLE_EQ(Median({7.0}), 7.0);
  // numpy.quantile([1, 2, 3, 4, 10], [0, 0.25, 0.9, 1]) = 1, 2, 7.6, 10
  const std::vector<double> v = {10.0, 1.0, 4.0, 2.0, 3.0};
  EXPECT_DOUBLE_EQ(Quantile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(Quantile(v, 0.25), 2.0);
  EXPECT_NEAR(Quantile(v, 0.9), 7.6, 1e-12);
  EXPECT_DOUBLE_EQ(Quantile(v, 1.0), 10.0);
  EXPECT_THROW(Median({}), std::invalid_argument);
  EXPECT_THROW(Quantile(v, 1.5), std::invalid_argument);
  EXPECT_THROW(Quantile(v, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
