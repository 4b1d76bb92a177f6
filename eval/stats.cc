#include "eval/stats.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "util/stats.h"

namespace waymark::eval {

ErrorStats ComputeStats(const std::vector<double>& errors) {
  if (errors.empty()) throw std::invalid_argument("statistics of an empty error list");
  ErrorStats stats;
  stats.count = errors.size();
  const double n = static_cast<double>(errors.size());
  double sum = 0.0;
  for (const double e : errors) {
    if (!std::isfinite(e)) throw std::invalid_argument("non-finite error value");
    sum += e;
    stats.sse += e * e;
  }
  stats.mean = sum / n;
  stats.rmse = std::sqrt(stats.sse / n);
  double squared_deviation = 0.0;
  for (const double e : errors) squared_deviation += (e - stats.mean) * (e - stats.mean);
  stats.std = std::sqrt(squared_deviation / n);

  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  stats.min = sorted.front();
  stats.max = sorted.back();
  stats.median = QuantileOfSorted(sorted, 0.5);
  return stats;
}

}  // namespace waymark::eval
