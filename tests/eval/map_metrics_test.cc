// Map against map: a rotated and translated copy of a true map, with known perturbations,
// in separate components that must be aligned separately.
#include "eval/map_metrics.h"

#include <gtest/gtest.h>

#include <cmath>

namespace waymark::eval {
namespace {

constexpr double kDeg = M_PI / 180.0;

MapMarker Marker(const std::string& id, const SE3d& T_world_marker,
                 std::optional<int> component = std::nullopt) {
  MapMarker m;
  m.key = {"apriltag-36h11", id};
  m.size_m = 0.16;
  m.T_world_marker = T_world_marker;
  m.component = component;
  return m;
}

SE3d Wall(double x, double y, double z, double yaw_deg) {
  // A marker on a wall: z out of the face, horizontal; then turned about world z.
  const Eigen::Matrix3d R_facing = (Eigen::AngleAxisd(yaw_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  return SE3d(R_facing, Eigen::Vector3d(x, y, z));
}

// Ground truth: component 0 is A, B, C, D at the corners of a 2 m square around (2, 3, 1.5)
// and E at its centre; component 1 is F (10, 0, 1) and G (12, 0, 1); H is only in the truth.
// Estimate: component 0 = T_a * (truth with A..D moved along z by +h, -h, +h, -h and B turned
// by 2 deg about its own x axis); component 1 = T_b * (truth with G moved by 0.2 m in y), plus X
// which the truth lacks.
// Expected, component 0 (aligned on positions): the z moves have zero sum and zero moments
//   with the centred x and y (-1,1,1,-1), (-1,-1,1,1), so the fit is exact: position errors
//   h, h, h, h, 0 and orientation errors 0, 2, 0, 0, 0 deg;
//   position RMS sqrt(4 h^2 / 5) = 0.0447213595 (h = 0.05), orientation RMS sqrt(4/5) = 0.894427191.
// Component 1 (2 markers: aligned on poses): orientations agree, so R is exact and
//   t = mean(p_gt - R p_est) splits the 0.2 m: position errors 0.1, 0.1; orientation 0.
// Overall: position RMS sqrt((4 * 0.0025 + 2 * 0.01) / 7) = 0.0654653671,
//   orientation RMS sqrt(4 / 7) = 0.755928946 deg, 7 markers.
struct MapCase {
  MarkerMap truth, estimate;
};

MapCase MakeMapCase() {
  constexpr double h = 0.05;
  MapCase c;
  const std::vector<std::tuple<std::string, double, double, double>> square = {
      {"A", 1, 2, h}, {"B", 3, 2, -h}, {"C", 3, 4, h}, {"D", 1, 4, -h}, {"E", 2, 3, 0.0}};
  const SE3d T_a(ExpSO3(Eigen::Vector3d(0.1, -0.2, 0.9)), Eigen::Vector3d(-5, 7, 0.3));
  for (const auto& [id, x, y, dz] : square) {
    const SE3d truth = Wall(x, y, 1.5, 30.0 * x);
    c.truth.markers.push_back(Marker(id, truth));
    SE3d moved(truth.rotation(), truth.translation() + Eigen::Vector3d(0, 0, dz));
    if (id == "B") moved = moved * SE3d(ExpSO3(Eigen::Vector3d(2 * kDeg, 0, 0)), Eigen::Vector3d::Zero());
    c.estimate.markers.push_back(Marker(id, T_a * moved, 0));
  }
  const SE3d T_b = SE3d::FromXYZYaw(100, -50, 2, 2.0);
  const SE3d F = Wall(10, 0, 1, 0), G = Wall(12, 0, 1, 180);
  c.truth.markers.push_back(Marker("F", F));
  c.truth.markers.push_back(Marker("G", G));
  c.truth.markers.push_back(Marker("H", Wall(0, 0, 1, 0)));
  c.estimate.markers.push_back(Marker("F", T_b * F, 1));
  c.estimate.markers.push_back(
      Marker("G", T_b * SE3d(G.rotation(), G.translation() + Eigen::Vector3d(0, 0.2, 0)), 1));
  c.estimate.markers.push_back(Marker("X", T_b * Wall(11, 0, 1, 0), 1));
  return c;
}

TEST(MapMetricsTest, TwoComponentsWithKnownPerturbations) {
  const MapCase c = MakeMapCase();
  const MapEvalResult r = EvaluateMap(c.estimate, c.truth);
  ASSERT_EQ(r.components.size(), 2u);
  const ComponentResult& c0 = r.components[0];
  EXPECT_EQ(c0.method, MapAlignmentMethod::kPositions);
  EXPECT_EQ(c0.markers, 5u);
  EXPECT_NEAR(c0.position_rmse_m, 0.0447213595499958, 1e-9);
  EXPECT_NEAR(c0.orientation_rmse_deg, 0.894427190999916, 1e-9);
  const ComponentResult& c1 = r.components[1];
  EXPECT_EQ(c1.method, MapAlignmentMethod::kPoses);
  EXPECT_EQ(c1.markers, 2u);
  EXPECT_EQ(c1.markers_total, 3u);
  EXPECT_NEAR(c1.position_rmse_m, 0.1, 1e-9);
  EXPECT_NEAR(c1.orientation_rmse_deg, 0.0, 1e-6);

  ASSERT_EQ(r.per_marker.size(), 7u);
  const std::vector<double> position_m = {0.05, 0.05, 0.05, 0.05, 0.0, 0.1, 0.1};
  const std::vector<double> orientation_deg = {0, 2, 0, 0, 0, 0, 0};
  for (size_t i = 0; i < 7; ++i) {
    EXPECT_NEAR(r.per_marker[i].position_error_m, position_m[i], 1e-9) << r.per_marker[i].key.id;
    EXPECT_NEAR(r.per_marker[i].orientation_error_deg, orientation_deg[i], 1e-6) << r.per_marker[i].key.id;
  }
  EXPECT_EQ(r.markers, 7u);
  EXPECT_NEAR(r.position_rmse_m, 0.0654653670707977, 1e-9);
  EXPECT_NEAR(r.orientation_rmse_deg, 0.755928946018454, 1e-9);
  ASSERT_EQ(r.missing_in_estimate.size(), 1u);
  EXPECT_EQ(r.missing_in_estimate[0].id, "H");
  ASSERT_EQ(r.missing_in_groundtruth.size(), 1u);
  EXPECT_EQ(r.missing_in_groundtruth[0].id, "X");
}

TEST(MapMetricsTest, ComponentsAreAlignedSeparately) {
  // Put every estimated marker in one component: the two rigid transforms can no longer
  // both be undone, and the errors grow far beyond the perturbations.
  MapCase c = MakeMapCase();
  for (MapMarker& m : c.estimate.markers) m.component = 0;
  EXPECT_GT(EvaluateMap(c.estimate, c.truth).position_rmse_m, 1.0);
}

TEST(MapMetricsTest, SingleMarkerAndCollinearComponentsUsePoses) {
  MarkerMap truth, estimate;
  const SE3d T(ExpSO3(Eigen::Vector3d(0.3, 0.2, -1.0)), Eigen::Vector3d(4, 5, 6));
  truth.markers.push_back(Marker("solo", Wall(1, 2, 3, 40)));
  estimate.markers.push_back(Marker("solo", T * Wall(1, 2, 3, 40), 4));
  for (int i = 0; i < 3; ++i) {  // three markers on one line
    truth.markers.push_back(Marker("line" + std::to_string(i), Wall(i, 0, 1, 0)));
    estimate.markers.push_back(Marker("line" + std::to_string(i), T * Wall(i, 0, 1, 0), 7));
  }
  const MapEvalResult r = EvaluateMap(estimate, truth);
  ASSERT_EQ(r.components.size(), 2u);
  EXPECT_EQ(r.components[0].component, 4);
  EXPECT_EQ(r.components[0].method, MapAlignmentMethod::kPoses);
  EXPECT_EQ(r.components[1].method, MapAlignmentMethod::kPoses);
  EXPECT_LT(r.position_rmse_m, 1e-9);
  EXPECT_LT(r.orientation_rmse_deg, 1e-6);
}

TEST(MapMetricsTest, CodesAlongOneWallAreAlignedByTheirPoses) {
  // [Bach]'s layout: codes every metre along one wall at one height, placed with a few
  // millimetres of error (`placed`), estimated with millimetre noise (`noise`, zero mean) and
  // exact orientations. On positions alone the rotation about the wall's line would be fitted
  // to those millimetres and tilt every code by degrees; on poses R is exact and each position
  // error is the noise itself: |noise_i| = 2.236, 2.236, 2, 2, 0 mm.
  const std::vector<Eigen::Vector3d> placed = {
      {0, 0.002, -0.003}, {0, -0.001, 0.001}, {0, 0.003, 0.002}, {0, 0.0, -0.002}, {0, -0.002, 0.001}};
  const std::vector<Eigen::Vector3d> noise = {
      {0, 0.001, 0.002}, {0, -0.001, -0.002}, {0, 0.0, 0.002}, {0, 0.0, -0.002}, {0, 0.0, 0.0}};
  const SE3d T(ExpSO3(Eigen::Vector3d(0.2, -0.1, 2.0)), Eigen::Vector3d(3, 1, 0));
  MarkerMap truth, estimate;
  for (int i = 0; i < 5; ++i) {
    const SE3d wall = Wall(i, 0, 1.2, 0);
    const SE3d placed_wall(wall.rotation(), wall.translation() + placed[i]);
    truth.markers.push_back(Marker("w" + std::to_string(i), placed_wall));
    estimate.markers.push_back(
        Marker("w" + std::to_string(i), T * SE3d(wall.rotation(), placed_wall.translation() + noise[i]), 0));
  }
  const MapEvalResult r = EvaluateMap(estimate, truth);
  ASSERT_EQ(r.components.size(), 1u);
  EXPECT_EQ(r.components[0].method, MapAlignmentMethod::kPoses);
  EXPECT_LT(r.orientation_rmse_deg, 1e-6);
  for (size_t i = 0; i < 5; ++i) EXPECT_NEAR(r.per_marker[i].position_error_m, noise[i].norm(), 1e-9);
}

// A 4 x 3 grid of codes on walls of several headings, 1 m apart in x and y at two heights (not
// collinear), for the predicted errors.
MarkerMap Grid(int component) {
  MarkerMap map;
  for (int i = 0; i < 12; ++i) {
    map.markers.push_back(Marker(std::to_string(component) + "-" + std::to_string(i),
                                 Wall(i % 4, i / 4, 1.0 + 0.5 * (i % 2), 30.0 * i), component));
  }
  return map;
}

// Independent isotropic errors sigma^2 I3 per code: the alignment's six parameters take six of
// the 3 N degrees of freedom, E[RMS^2] = sigma^2 (3 N - 6) / N; in the map's frame 3 sigma^2.
TEST(MapMetricsTest, PredictedErrorOfIndependentMarkers) {
  const double sigma = 0.004;
  MarkerMap map = Grid(0);
  for (MapMarker& m : map.markers) {
    m.covariance = Matrix6d::Identity() * 1e-6;
    m.covariance->bottomRightCorner<3, 3>() = sigma * sigma * Eigen::Matrix3d::Identity();
  }
  const std::vector<PredictedComponentError> p = PredictMapError(map);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_FALSE(p[0].joint);
  EXPECT_EQ(p[0].markers, 12u);
  EXPECT_NEAR(p[0].rms_m, std::sqrt(3.0) * sigma, 1e-12);
  EXPECT_NEAR(p[0].aligned_rms_m, sigma * std::sqrt((3.0 * 12 - 6) / 12), 1e-12);
}

// A shared error (the covariance factor) that is a rigid motion of the whole map: the alignment
// takes it out whole; a shared error that is not rigid (one code's) stays.
TEST(MapMetricsTest, PredictedErrorRemovesSharedRigidMotion) {
  MarkerMap map = Grid(3);
  const Eigen::Vector3d omega(0.0, 0.0, 0.01);  // rad, about the grid's centre
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const MapMarker& m : map.markers) centre += m.T_world_marker.translation() / 12.0;
  for (MapMarker& m : map.markers) {
    // Factor columns (body tangent [r t]): a world translation of 5 mm along x, and the rotation
    // omega about the centre, whose world position effect is omega x (p - centre).
    const Eigen::Matrix3d R = m.T_world_marker.rotation().toRotationMatrix();
    CovarianceFactor F = CovarianceFactor::Zero(6, 2);
    F.block<3, 1>(3, 0) = R.transpose() * Eigen::Vector3d(0.005, 0.0, 0.0);
    F.block<3, 1>(3, 1) = R.transpose() * omega.cross(m.T_world_marker.translation() - centre);
    m.covariance_factor = F;
    m.covariance = Matrix6d(F * F.transpose()) + 1e-14 * Matrix6d::Identity();
  }
  std::vector<PredictedComponentError> p = PredictMapError(map);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_TRUE(p[0].joint);
  EXPECT_GT(p[0].rms_m, 0.005);
  EXPECT_LT(p[0].aligned_rms_m, 1e-6);

  // Code 0 alone moves 6 mm along y on top (a second, independent term of its marginal): the
  // alignment removes its mean and moments over the 12 codes, E = 36e-6 (1 - a) / 12 with a the
  // leverage A_0 (A^T A)^-1 A_0^T's (y, y) entry, between 0 and 1.
  map.markers[0].covariance->bottomRightCorner<3, 3>() +=
      map.markers[0].T_world_marker.rotation().toRotationMatrix().transpose() *
      Eigen::Vector3d(0.0, 0.006 * 0.006, 0.0).asDiagonal() *
      map.markers[0].T_world_marker.rotation().toRotationMatrix();
  p = PredictMapError(map);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_GT(p[0].aligned_rms_m, 0.006 * std::sqrt(0.5 / 12));
  EXPECT_LT(p[0].aligned_rms_m, 0.006 * std::sqrt(1.0 / 12));
}

// No prediction for a component with a free code without covariance, or with collinear codes;
// fixed codes (anchors) count with no error.
TEST(MapMetricsTest, PredictedErrorNeedsCovariancesAndSpread) {
  MarkerMap map = Grid(0);
  for (MapMarker& m : map.markers) m.covariance = Matrix6d::Identity() * 1e-6;
  map.markers[0].covariance.reset();
  EXPECT_TRUE(PredictMapError(map).empty());
  map.markers[0].fixed = true;
  std::vector<PredictedComponentError> p = PredictMapError(map);
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NEAR(p[0].rms_m, std::sqrt(11.0 * 3e-6 / 12), 1e-12);
  MarkerMap line;
  for (int i = 0; i < 5; ++i) {
    line.markers.push_back(Marker("L" + std::to_string(i), Wall(i, 0.0, 1.0, 0.0)));
    line.markers.back().covariance = Matrix6d::Identity() * 1e-6;
  }
  EXPECT_TRUE(PredictMapError(line).empty());
}

TEST(MapMetricsTest, BadInput) {
  MapCase c = MakeMapCase();
  MarkerMap duplicated = c.estimate;
  duplicated.markers.push_back(duplicated.markers.front());
  EXPECT_THROW(EvaluateMap(duplicated, c.truth), std::invalid_argument);
  MarkerMap other;
  other.markers.push_back(Marker("nobody", SE3d()));
  EXPECT_THROW(EvaluateMap(other, c.truth), std::runtime_error);
  EXPECT_THROW(AlignByPoses({}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace waymark::eval
