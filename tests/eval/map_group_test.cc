// eval::EvaluateGroup: marker RMS of the ids matching a pattern and of the others.
#include <gtest/gtest.h>

#include "eval/map_metrics.h"

namespace waymark::eval {
namespace {

MapMarker Marker(const std::string& id, const Eigen::Vector3d& t) {
  MapMarker m;
  m.key = {"qr", id};
  m.size_m = 0.1;
  m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), t);
  return m;
}

TEST(MapGroupTest, SplitsLoadsFromFloorCodes) {
  MarkerMap gt, est;
  const std::vector<std::pair<std::string, Eigen::Vector3d>> codes = {
      {"0/0/0", {0, 0, 0}}, {"0/4/0", {4, 0, 0}}, {"0/0/3", {0, 3, 0}},
      {"0/4/3", {4, 3, 0}}, {"1/A", {1, 1, 1}},   {"1/B", {3, 2, 1}}};
  for (const auto& [id, t] : codes) {
    gt.markers.push_back(Marker(id, t));
    // Loads 3 cm off along z (both the same way), floor codes exact.
    est.markers.push_back(
        Marker(id, t + (id[0] == '1' ? Eigen::Vector3d(0, 0, 0.03) : Eigen::Vector3d::Zero())));
  }
  const MapEvalResult result = EvaluateMap(est, gt);
  const GroupResult group = EvaluateGroup(result, "^1/");
  EXPECT_EQ(group.markers, 2u);
  EXPECT_EQ(group.markers_other, 4u);
  // The Umeyama fit over all six moves everything by the mean offset 1 cm in z: loads 2 cm off,
  // floor codes 1 cm off.
  EXPECT_NEAR(group.position_rmse_m, 0.02, 1e-9);
  EXPECT_NEAR(group.other_position_rmse_m, 0.01, 1e-9);
  EXPECT_NEAR(group.orientation_rmse_deg, 0.0, 1e-9);
  const GroupResult none = EvaluateGroup(result, "^9/");
  EXPECT_EQ(none.markers, 0u);
  EXPECT_EQ(none.position_rmse_m, 0.0);
  EXPECT_THROW(EvaluateGroup(result, "(unclosed"), std::invalid_argument);
}

}  // namespace
}  // namespace waymark::eval
