// The identity check (mapping/id_consistency.h) on simulated surveys whose misdecoded views are
// known (sim::SimResult::true_keys).
#include "mapping/id_consistency.h"

#include <gtest/gtest.h>

#include <set>

#include "mapping/initializer.h"
#include "sim/simulator.h"

namespace waymark {
namespace {

struct Counts {
  size_t flagged = 0, flagged_swapped = 0, swapped = 0;
};

// Compares the flagged views with the truth. Only swaps into another real code's id are judged
// (random text makes a code of its own, seen once, which the check has nothing to compare with).
Counts Judge(const sim::SimResult& sim, const Survey& survey, const std::vector<int>& flagged) {
  std::set<std::string> real_ids;
  for (const MapMarker& m : sim.dataset.groundtruth_markers->markers) real_ids.insert(m.key.ToString());
  std::set<int> flagged_set(flagged.begin(), flagged.end());
  Counts counts;
  counts.flagged = flagged.size();
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    const SurveyObservation& obs = survey.observations[o];
    const DetectionFrame& frame = sim.dataset.detections[obs.detection_line];
    size_t j = 0;
    while (j < frame.markers.size() && frame.markers[j].key != survey.markers[obs.marker].key) ++j;
    EXPECT_LT(j, frame.markers.size());
    if (j == frame.markers.size()) continue;
    const MarkerKey& truth = sim.true_keys[obs.detection_line][j];
    const bool swapped = truth != frame.markers[j].key && real_ids.count(frame.markers[j].key.ToString()) > 0;
    counts.swapped += swapped ? 1 : 0;
    counts.flagged_swapped += (swapped && flagged_set.count(static_cast<int>(o))) ? 1 : 0;
  }
  return counts;
}

sim::SimResult Corridor(std::uint64_t seed, double misdecode_fraction) {
  sim::ParamSet params = sim::ScenarioParams("corridor");
  params.SetAssignment("detect.misdecode_fraction=" + std::to_string(misdecode_fraction));
  return sim::Simulate("corridor", params, seed);
}

TEST(IdConsistencyTest, FindsSwappedIdsAndSparesCorrectOnes) {
  const sim::SimResult sim = Corridor(2, 0.1);
  const Survey survey = IngestDataset(sim.dataset);
  const std::vector<int> flagged = FindInconsistentIds(survey, MakeCameras(survey));
  const Counts counts = Judge(sim, survey, flagged);
  std::cerr << counts.flagged << " flagged, " << counts.flagged_swapped << " of " << counts.swapped
            << " swapped ids among them\n";
  ASSERT_GT(counts.swapped, 20u);
  EXPECT_GE(counts.flagged_swapped, 0.9 * counts.swapped);  // recall
  EXPECT_GE(counts.flagged_swapped, 0.9 * counts.flagged);  // precision
}

TEST(IdConsistencyTest, CleanSurveyLosesNothing) {
  const sim::SimResult sim = Corridor(2, 0.0);
  const Survey survey = IngestDataset(sim.dataset);
  EXPECT_TRUE(FindInconsistentIds(survey, MakeCameras(survey)).empty());
}

// A drone whose visual odometry drifts ten times the default (2 deg/m of yaw drift, 5 % scale
// error): the code under its start is seen again after a loop, metres off along the odometry.
// Each visit is a run of views that agree with each other: none is a misdecoded id (before the
// visit rule, 42 correct views of two codes were set aside).
TEST(IdConsistencyTest, RevisitAfterLargeDriftIsNoMisdecode) {
  sim::ParamSet params = sim::ScenarioParams("warehouse-drone");
  for (const char* assignment : {"odometry.trans_per_m=0.1", "odometry.rot_per_rad=0.1",
                                 "odometry.yaw_drift_deg_per_m=2", "odometry.scale_error=0.05"})
    params.SetAssignment(assignment);
  const sim::SimResult sim = sim::Simulate("warehouse-drone", params, 3);
  const Survey survey = IngestDataset(sim.dataset);
  EXPECT_TRUE(FindInconsistentIds(survey, MakeCameras(survey)).empty());
  // Without the visit rule (a visit must be larger than the survey) the old verdict returns.
  IdCheckOptions options;
  options.min_visit_views = 1000000;
  EXPECT_GT(FindInconsistentIds(survey, MakeCameras(survey), options).size(), 10u);
}

TEST(IdConsistencyTest, WithoutObservationsRenumbers) {
  const sim::SimResult sim = Corridor(2, 0.0);
  const Survey survey = IngestDataset(sim.dataset);
  ASSERT_GT(survey.observations.size(), 10u);
  const Survey out = WithoutObservations(survey, {0, 3, 7});
  ASSERT_EQ(out.observations.size(), survey.observations.size() - 3);
  EXPECT_EQ(out.frames.size(), survey.frames.size());
  EXPECT_EQ(out.markers.size(), survey.markers.size());
  size_t listed = 0;
  for (size_t f = 0; f < out.frames.size(); ++f) {
    for (int o : out.frames[f].observations) {
      EXPECT_EQ(out.observations[o].frame, static_cast<int>(f));
      ++listed;
    }
  }
  EXPECT_EQ(listed, out.observations.size());
  for (size_t m = 0; m < out.markers.size(); ++m) {
    for (int o : out.markers[m].observations) EXPECT_EQ(out.observations[o].marker, static_cast<int>(m));
  }
  EXPECT_EQ(out.observations[0].corners_px[0], survey.observations[1].corners_px[0]);
  EXPECT_THROW(WithoutObservations(survey, {static_cast<int>(survey.observations.size())}),
               std::out_of_range);
}

TEST(IdConsistencyTest, RejectsBadOptions) {
  IdCheckOptions options;
  options.drift_per_m = -1.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("drift_per_m"), std::string::npos);
  IdCheckOptions visits;
  visits.min_visit_views = 1;
  EXPECT_FALSE(visits.Check(&why));
  EXPECT_NE(why.find("min_visit_views"), std::string::npos);
  const sim::SimResult sim = Corridor(2, 0.0);
  const Survey survey = IngestDataset(sim.dataset);
  EXPECT_THROW(FindInconsistentIds(survey, MakeCameras(survey), options), std::runtime_error);
}

}  // namespace
}  // namespace waymark
