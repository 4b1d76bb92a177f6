// Order statistics, in one place (eval/stats.h's ErrorStats, map scores, latency and timing
// summaries all use these).
#pragma once

#include <vector>

namespace waymark {

// The q-quantile (0 <= q <= 1) of `values` by linear interpolation between the order statistics
// (numpy's default, "type 7"): position h = q (n - 1), value x[floor h] + (h - floor h)
// (x[floor h + 1] - x[floor h]) of the sorted values. Quantile(v, 0.5) is the median: the middle
// value, or the mean of the two middle values when n is even (evo's and numpy's median).
// Throws std::invalid_argument for an empty list or q outside [0, 1] (NaN included).
double Quantile(std::vector<double> values, double q);
double Median(std::vector<double> values);

// The same on values already sorted ascending (no copy).
double QuantileOfSorted(const std::vector<double>& sorted, double q);

}  // namespace waymark
