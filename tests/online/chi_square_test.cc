#include "online/chi_square.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace waymark {
namespace {

// Reference quantiles from printed chi-square tables.
TEST(ChiSquareTest, QuantileMatchesTables) {
  EXPECT_NEAR(ChiSquareQuantile(0.95, 1), 3.841, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.99, 2), 9.210, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 3), 7.815, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.999, 3), 16.266, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 8), 15.507, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.025, 10), 3.247, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.975, 100), 129.561, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.025, 100), 74.222, 1e-3);
}

TEST(ChiSquareTest, CdfInvertsQuantile) {
  for (int dof : {1, 2, 3, 4, 8, 60, 600}) {
    for (double p : {0.001, 0.025, 0.5, 0.975, 0.997}) {
      EXPECT_NEAR(ChiSquareCdf(ChiSquareQuantile(p, dof), dof), p, 1e-9) << dof << " " << p;
    }
  }
  // dof 2 has the closed form 1 - exp(-x/2).
  EXPECT_NEAR(ChiSquareCdf(3.0, 2), 1.0 - std::exp(-1.5), 1e-12);
}

TEST(ChiSquareTest, RejectsBadArguments) {
  EXPECT_THROW(ChiSquareQuantile(0.0, 3), std::invalid_argument);
  EXPECT_THROW(ChiSquareQuantile(1.0, 3), std::invalid_argument);
  EXPECT_THROW(ChiSquareQuantile(0.5, 0), std::invalid_argument);
  EXPECT_THROW(RegularizedLowerGamma(-1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(RegularizedLowerGamma(1.0, std::nan("")), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
