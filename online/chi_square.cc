#include "online/chi_square.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace waymark {
namespace {

constexpr int kMaxTerms = 1000;
constexpr double kEpsilon = 1e-15;
constexpr double kTiny = 1e-300;

// Series: P(a, x) = x^a e^-x / Gamma(a + 1) * sum_n x^n / ((a + 1) ... (a + n)).
double LowerGammaSeries(double a, double x) {
  double term = 1.0 / a;
  double sum = term;
  for (int n = 1; n < kMaxTerms; ++n) {
    term *= x / (a + n);
    sum += term;
    if (std::abs(term) < std::abs(sum) * kEpsilon) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Continued fraction (modified Lentz) for Q(a, x) = 1 - P(a, x):
//   Q = x^a e^-x / Gamma(a) * 1 / (x + 1 - a - 1 (1 - a) / (x + 3 - a - 2 (2 - a) / (x + 5 - a - ...)))
double UpperGammaFraction(double a, double x) {
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny;
  double d = 1.0 / b;
  double h = d;
  for (int n = 1; n < kMaxTerms; ++n) {
    const double an = -n * (n - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < kEpsilon) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

}  // namespace

double RegularizedLowerGamma(double a, double x) {
  if (!std::isfinite(a) || !std::isfinite(x) || a <= 0.0 || x < 0.0) {
    throw std::invalid_argument("RegularizedLowerGamma: expected a > 0 and x >= 0, got a = " +
                                std::to_string(a) + ", x = " + std::to_string(x));
  }
  if (x == 0.0) return 0.0;
  if (x < a + 1.0) return LowerGammaSeries(a, x);
  return 1.0 - UpperGammaFraction(a, x);
}

double ChiSquareCdf(double x, int dof) {
  if (dof < 1) throw std::invalid_argument("ChiSquareCdf: expected dof >= 1, got " + std::to_string(dof));
  if (x <= 0.0) return 0.0;
  return RegularizedLowerGamma(0.5 * dof, 0.5 * x);
}

double ChiSquareQuantile(double probability, int dof) {
  if (!(probability > 0.0 && probability < 1.0) || dof < 1) {
    throw std::invalid_argument("ChiSquareQuantile: expected probability in (0, 1) and dof >= 1, got " +
                                std::to_string(probability) + ", " + std::to_string(dof));
  }
  double low = 0.0;
  double high = dof + 10.0;
  while (ChiSquareCdf(high, dof) < probability) high *= 2.0;
  for (int i = 0; i < 200 && high - low > 1e-12 * high; ++i) {
    const double mid = 0.5 * (low + high);
    (ChiSquareCdf(mid, dof) < probability ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

}  // namespace waymark
