// Summary statistics of a list of errors, with evo's definitions (evo/core/metrics.py
// PE.get_statistic), so that our figures equal `evo_ape` / `evo_rpe` on the same data:
//   rmse   = sqrt( (1/n) sum e_i^2 )
//   mean   = (1/n) sum e_i
//   median = middle value of the sorted e_i; mean of the two middle values when n is even
//   std    = sqrt( (1/n) sum (e_i - mean)^2 )        (population, numpy's ddof = 0)
//   min, max, sse = sum e_i^2
#pragma once

#include <cstddef>
#include <vector>

namespace waymark::eval {

struct ErrorStats {
  size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std = 0.0;
  double min = 0.0;
  double max = 0.0;
  double sse = 0.0;
};

// Throws std::invalid_argument for an empty list or a non-finite error.
ErrorStats ComputeStats(const std::vector<double>& errors);

}  // namespace waymark::eval
