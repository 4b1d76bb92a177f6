#include "util/stats.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace waymark {

double QuantileOfSorted(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) throw std::invalid_argument("quantile of an empty list");
  if (!(q >= 0.0 && q <= 1.0)) throw std::invalid_argument("quantile: q must be in [0, 1]");
  const double h = q * static_cast<double>(sorted.size() - 1);
  const size_t below = static_cast<size_t>(std::floor(h));
  if (below + 1 >= sorted.size()) return sorted.back();
  const double fraction = h - static_cast<double>(below);
  if (fraction == 0.0) return sorted[below];
  if (fraction == 0.5) return 0.5 * (sorted[below] + sorted[below + 1]);  // the even median, exactly
  return sorted[below] + fraction * (sorted[below + 1] - sorted[below]);
}

double Quantile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return QuantileOfSorted(values, q);
}

double Median(std::vector<double> values) { return Quantile(std::move(values), 0.5); }

}  // namespace waymark
