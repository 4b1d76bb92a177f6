// Chi-square distribution helpers for innovation gating and NEES bounds.
//
//   ChiSquareCdf(x, k)      = P(k/2, x/2), the regularized lower incomplete gamma function
//   ChiSquareQuantile(p, k) = the x with ChiSquareCdf(x, k) = p
//
// P(a, x) is evaluated by its power series for x < a + 1 and by the continued fraction of
// the upper function Q = 1 - P otherwise (both converge fast in their region); the
// quantile is found by bisection on the monotone CDF, to a relative 1e-12.
#pragma once

namespace waymark {

// Regularized lower incomplete gamma P(a, x), a > 0, x >= 0. Throws std::invalid_argument
// for a <= 0, x < 0 or non-finite arguments.
double RegularizedLowerGamma(double a, double x);

// CDF of the chi-square distribution with `dof` degrees of freedom (dof >= 1).
double ChiSquareCdf(double x, int dof);

// Inverse CDF: the gate threshold for probability p in (0, 1) and `dof` >= 1.
// Throws std::invalid_argument otherwise.
double ChiSquareQuantile(double probability, int dof);

}  // namespace waymark
