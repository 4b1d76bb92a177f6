// Where a map build's time and memory went: one entry per phase (ingest, id check, single views,
// local maps, ..., covariance), with the process's peak resident set size when the phase ended.
#pragma once

#include <chrono>
#include <string>
#include <vector>

namespace waymark {

struct PhaseTime {
  std::string phase;
  double seconds = 0.0;
  double peak_rss_mb = 0.0;  // of the whole process, at the phase's end (0 where unknown)
};

// The process's peak resident set size so far, in MiB (getrusage; 0 where unavailable).
double PeakRssMb();

// Appends a PhaseTime to `phases` at each Lap: the time since the previous Lap (or construction).
class PhaseClock {
 public:
  explicit PhaseClock(std::vector<PhaseTime>* phases)
      : phases_(phases), last_(std::chrono::steady_clock::now()) {}
  void Lap(const std::string& phase);

 private:
  std::vector<PhaseTime>* phases_;
  std::chrono::steady_clock::time_point last_;
};

// "ingest 0.41 s, id check 0.02 s, ...; peak memory 812 MiB": one line for the build summary.
std::string FormatPhases(const std::vector<PhaseTime>& phases);

}  // namespace waymark
