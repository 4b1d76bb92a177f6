#include "mapping/build_stats.h"

#include <sys/resource.h>

#include <algorithm>
#include <sstream>

namespace waymark {

double PeakRssMb() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux: KiB
}

void PhaseClock::Lap(const std::string& phase) {
  const auto now = std::chrono::steady_clock::now();
  phases_->push_back({phase, std::chrono::duration<double>(now - last_).count(), PeakRssMb()});
  last_ = now;
}

std::string FormatPhases(const std::vector<PhaseTime>& phases) {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  double total = 0.0, peak = 0.0;
  for (size_t i = 0; i < phases.size(); ++i) {
    out.precision(phases[i].seconds < 10.0 ? 2 : 1);
    out << (i > 0 ? ", " : "") << phases[i].phase << " " << phases[i].seconds << " s";
    total += phases[i].seconds;
    peak = std::max(peak, phases[i].peak_rss_mb);
  }
  out.precision(2);
  out << "; total " << total << " s";
  out.precision(0);
  if (peak > 0.0) out << "; peak memory " << peak << " MiB";
  return out.str();
}

}  // namespace waymark
