// Mapping on the real TagSLAM sets (../shared/data/tagslam, see its README): test16's tag centres
// on one line, our reprojection error side by side with TagSLAM's reference solution scored on the
// same observations, and test22's T265 odometry, whose clock is off its images'. Skips with a
// message when the shared data folder is absent (a fresh clone).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "mapping/map_builder.h"
#include "mapping/map_score.h"

namespace waymark {
namespace {

std::filesystem::path SetPath(const std::string& name) {
  return std::filesystem::path(WAYMARK_SHARED_DATA) / "tagslam" / name;
}

#define SKIP_WITHOUT(dir)                                                               \
  if (!std::filesystem::exists(dir)) {                                                  \
    GTEST_SKIP() << "shared data absent: " << (dir) << " (tests on real data skipped)"; \
  }

MapBuildResult Build(const Dataset& dataset) {
  MapBuildOptions options;
  options.compute_covariance = false;
  return BuildMap(dataset, options);
}

// TagSLAM's reference: its trajectory held fixed, the tags its markers.json lacks solved on the
// same corners (mapping/map_score.h).
MapScore ScoreReference(const Dataset& dataset) {
  MapScoreOptions options;
  options.solve_missing_markers = true;
  return ScoreMap(dataset, ReadMap(dataset.dir / "reference/markers.json"),
                  ReadTum(dataset.dir / "reference/trajectory.tum"), options);
}

TEST(TagslamTest, Test16TagCentresLieOnOneLine) {
  SKIP_WITHOUT(SetPath("tagslam-test16"));
  const Dataset dataset = LoadDataset(SetPath("tagslam-test16"));
  const MapBuildResult result = Build(dataset);
  ASSERT_EQ(result.map.markers.size(), 5u);
  EXPECT_TRUE(result.outliers.empty());
  std::vector<Eigen::Vector3d> centres_world;
  for (const MapMarker& m : result.map.markers) centres_world.push_back(m.T_world_marker.translation());
  const LineFit line = FitLine(centres_world);
  // The tags are 0.16 m wide and span about 1.3 m; measured 7.1 mm RMS, 12.5 mm max (TagSLAM's own
  // solution gives the same figures).
  EXPECT_LT(line.rms_m, 0.010);
  EXPECT_LT(line.max_m, 0.020);
  std::cerr << "test16 line fit: RMS " << 1e3 * line.rms_m << " mm, max " << 1e3 * line.max_m << " mm\n";
}

TEST(TagslamTest, OursMatchesTheReferenceOnTheSameObservations) {
  for (const std::string name : {"tagslam-test16", "tagslam-test17"}) {
    SKIP_WITHOUT(SetPath(name));
    const Dataset dataset = LoadDataset(SetPath(name));
    const MapBuildResult result = Build(dataset);
    const MapScore ours = ScoreMap(dataset, result.map, result.trajectory);
    const MapScore reference = ScoreReference(dataset);
    EXPECT_EQ(ours.all.observations, ours.observations) << name;
    EXPECT_EQ(reference.all.observations, reference.observations) << name;
    EXPECT_LT(ours.all.rms_px, 0.15) << name;  // measured 0.097 (test16), 0.103 (test17)
    EXPECT_LE(ours.all.rms_px, 1.02 * reference.all.rms_px) << name;
    std::cerr << name << ": ours " << ours.all.rms_px << " px, reference " << reference.all.rms_px << " px\n";
  }
}

TEST(TagslamTest, Test22OdometryClockOffsetIsFoundAndTheObservationsKept) {
  SKIP_WITHOUT(SetPath("tagslam-test22"));
  const Dataset dataset = LoadDataset(SetPath("tagslam-test22"));
  const Survey survey = IngestDataset(dataset);
  // The reference trajectory against the odometry gives -0.42 to -0.5 s (docs/mapping.md).
  EXPECT_GT(survey.odometry_time_offset_s, -0.6);
  EXPECT_LT(survey.odometry_time_offset_s, -0.35);
  const MapBuildResult result = Build(dataset);
  // 105 observations: 87 were rejected on the image clock with the plain noise model; none now.
  EXPECT_GE(result.observations, 100u);
  const MapScore ours = ScoreMap(dataset, result.map, result.trajectory);
  EXPECT_EQ(ours.all.observations, 105u);
  EXPECT_LT(ours.all.rms_px, 0.5);  // measured 0.30 px; TagSLAM's reference 0.38 px on its 99
  // Ablations: on the images' clock about half the observations disagree with the odometry
  // (measured 54 used); without the interpolation term the far, jerky frames do (92 used).
  MapBuildOptions options;
  options.compute_covariance = false;
  options.ingest.estimate_time_offset = false;
  EXPECT_LT(BuildMap(dataset, options).observations, 70u);
  options.ingest.estimate_time_offset = true;
  options.ingest.interpolation_noise = false;
  EXPECT_LT(BuildMap(dataset, options).observations, 100u);
  std::cerr << "test22: offset " << survey.odometry_time_offset_s << " s, " << result.observations
            << " observations used, " << result.outliers.size() << " rejected; ours RMS " << ours.all.rms_px
            << " px (median " << ours.all.median_px << "), reference " << ScoreReference(dataset).all.rms_px
            << " px\n";
}

// test10-priors: 82 tags given as priors of sigma 0.5 m / 0.1 rad (TagSLAM's own inputs, some
// tens of centimetres off), no odometry, long stretches with one tag in view. The groups of tags
// that share no observation were 5 components, each in its own frame, and the trajectory of
// component 0 covered 494 of the 3 094 observations; the priors put every group in the world
// frame, so it is one map now, its trajectory in that frame. TagSLAM: one map, 3 078
// observations used, RMS 0.351 px, median 0.158 px.
TEST(TagslamTest, Test10PriorsMakeOneMapInTheWorldFrame) {
  SKIP_WITHOUT(SetPath("tagslam-test10-priors"));
  const Dataset dataset = LoadDataset(SetPath("tagslam-test10-priors"));
  const MapBuildResult result = Build(dataset);
  ASSERT_EQ(result.components.size(), 1u);
  EXPECT_GE(result.observations, static_cast<size_t>(0.99 * 3078));
  const MapScore ours = ScoreMap(dataset, result.map, result.trajectory);
  // 3 093 read (one corner 57 px out of the image), one of a code read under a wrong id.
  EXPECT_EQ(ours.all.observations, 3092u);
  const MapScore reference = ScoreReference(dataset);
  // Measured: ours 0.331 px RMS over the 3 087 used (0.383 over all 3 092 with the 5 rejected),
  // median 0.182; TagSLAM's solution 0.351 px, median 0.183 over the 3 077 it has poses for.
  ASSERT_EQ(result.reprojection.size(), 1u);
  EXPECT_LE(result.reprojection[0].rms_px, reference.all.rms_px);
  EXPECT_LE(ours.all.median_px, 1.02 * reference.all.median_px);
  std::cerr << "test10-priors: " << result.map.markers.size() << " tags, " << result.observations
            << " observations used, " << result.outliers.size() << " rejected; ours RMS " << ours.all.rms_px
            << " px (median " << ours.all.median_px << ") over " << ours.all.observations << "\n";
}

}  // namespace
}  // namespace waymark
