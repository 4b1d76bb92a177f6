// The simulator's contract: the seed draws only the noise, every emitted corner is the true
// projection plus the stated noise, the detection limits hold, the rooms' components are
// what the scenario intends, payloads carry true coordinates, the misdecode fraction and the
// odometry noise are what dataset.yaml and the parameters say.
#include "sim/simulator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <regex>
#include <set>

#include "geometry/camera.h"

namespace waymark::sim {
namespace {

SimResult RunSim(const std::string& scenario, const std::vector<std::string>& sets, std::uint64_t seed) {
  ParamSet params = ScenarioParams(scenario);
  for (const std::string& s : sets) params.SetAssignment(s);
  return Simulate(scenario, params, seed);
}

const std::vector<std::string> kNoiseless = {"detect.pixel_sigma_px=0", "detect.miss_fraction=0",
                                             "detect.misdecode_fraction=0"};

std::map<double, SE3d> PosesByStamp(const Trajectory& trajectory) {
  std::map<double, SE3d> poses;
  for (const StampedSE3& s : trajectory) poses[s.stamp_s] = s.T;
  return poses;
}

// Calls f(frame, observation, T_world_camera, true marker) for every emitted observation.
template <typename F>
void ForEachObservation(const SimResult& r, F f) {
  const auto poses = PosesByStamp(*r.dataset.groundtruth_trajectory);
  for (size_t i = 0; i < r.dataset.detections.size(); ++i) {
    const DetectionFrame& frame = r.dataset.detections[i];
    const CameraInfo& camera = r.dataset.cameras.at(frame.camera);
    const SE3d T_world_camera = poses.at(frame.stamp_s) * camera.T_robot_camera;
    for (size_t j = 0; j < frame.markers.size(); ++j) {
      const MapMarker* truth = r.dataset.groundtruth_markers->Find(r.true_keys[i][j]);
      ASSERT_NE(truth, nullptr);
      f(frame, frame.markers[j], T_world_camera, *truth);
    }
  }
}

// Corner pixel differences (observed - true projection), stacked.
std::vector<double> CornerResiduals(const SimResult& r) {
  std::vector<double> residuals;
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : r.dataset.cameras) cameras.emplace(name, Camera(info));
  ForEachObservation(r, [&](const DetectionFrame& frame, const MarkerObservation& obs,
                            const SE3d& T_world_camera, const MapMarker& truth) {
    const auto corners = MarkerCorners(truth.size_m);
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector3d corner_camera = T_world_camera.inverse() * (truth.T_world_marker * corners[c]);
      const auto px = cameras.at(frame.camera).Project(corner_camera);
      ASSERT_TRUE(px.has_value());
      residuals.push_back(obs.corners_px[c].x() - px->x());
      residuals.push_back(obs.corners_px[c].y() - px->y());
    }
  });
  return residuals;
}

TEST(SimulatorTest, EveryScenarioProducesDetectionsForEveryFrame) {
  for (const ScenarioInfo& scenario : Scenarios()) {
    const SimResult r = RunSim(scenario.name, {}, 1);
    const size_t cameras = r.dataset.cameras.size();
    const size_t samples = r.dataset.groundtruth_trajectory->size();
    EXPECT_EQ(r.dataset.odometry.size(), samples) << scenario.name;
    EXPECT_EQ(r.dataset.detections.size(), cameras * ((samples + 1) / 2)) << scenario.name;  // 20 Hz / 10 Hz
    EXPECT_GT(r.stats.detections, 200) << scenario.name;
    std::set<MarkerKey> seen;
    for (const DetectionFrame& f : r.dataset.detections) {
      for (const MarkerObservation& m : f.markers) seen.insert(m.key);
    }
    // Most codes of the place are seen at least once.
    EXPECT_GT(seen.size(), 0.8 * r.dataset.groundtruth_markers->markers.size()) << scenario.name;
  }
}

TEST(SimulatorTest, CorridorPathIsAbout40mAndStaysInDetectionRangeOfTheWalls) {
  const SimResult r = RunSim("corridor", {}, 1);
  EXPECT_NEAR(r.stats.path_length_m, 40.0, 0.5);
  const SE3d& start = r.dataset.groundtruth_trajectory->front().T;
  const SE3d& end = r.dataset.groundtruth_trajectory->back().T;
  EXPECT_LT((start.translation() - end.translation()).norm(), 1e-9);  // closed loop
  for (const StampedSE3& s : *r.dataset.groundtruth_trajectory) {
    // Centre line of the 12 x 8 m loop, 0.6 m from both walls.
    const double x = s.T.translation().x(), y = s.T.translation().y();
    const double to_centre_line = std::min({std::abs(x), std::abs(x - 12.0), std::abs(y), std::abs(y - 8.0)});
    EXPECT_LT(to_centre_line, 1e-9);
  }
}

TEST(SimulatorTest, SameSeedGivesIdenticalOutput) {
  const SimResult a = RunSim("warehouse-drone", {"detect.misdecode_fraction=0.05"}, 7);
  const SimResult b = RunSim("warehouse-drone", {"detect.misdecode_fraction=0.05"}, 7);
  ASSERT_EQ(a.dataset.detections.size(), b.dataset.detections.size());
  for (size_t i = 0; i < a.dataset.detections.size(); ++i) {
    const auto& fa = a.dataset.detections[i];
    const auto& fb = b.dataset.detections[i];
    ASSERT_EQ(fa.markers.size(), fb.markers.size());
    for (size_t j = 0; j < fa.markers.size(); ++j) {
      EXPECT_EQ(fa.markers[j].key, fb.markers[j].key);
      for (int c = 0; c < 4; ++c) EXPECT_EQ(fa.markers[j].corners_px[c], fb.markers[j].corners_px[c]);
    }
  }
  ASSERT_EQ(a.dataset.odometry.size(), b.dataset.odometry.size());
  for (size_t k = 0; k < a.dataset.odometry.size(); ++k) {
    EXPECT_EQ(a.dataset.odometry[k].T.matrix(), b.dataset.odometry[k].T.matrix());
  }
}

TEST(SimulatorTest, DifferentSeedSamePlaceDifferentNoise) {
  for (const ScenarioInfo& scenario : Scenarios()) {
    const SimResult a = RunSim(scenario.name, {}, 1);
    const SimResult b = RunSim(scenario.name, {}, 2);
    const auto& ma = a.dataset.groundtruth_markers->markers;
    const auto& mb = b.dataset.groundtruth_markers->markers;
    ASSERT_EQ(ma.size(), mb.size());
    for (size_t i = 0; i < ma.size(); ++i) {
      EXPECT_EQ(ma[i].key, mb[i].key);
      EXPECT_EQ(ma[i].T_world_marker.matrix(), mb[i].T_world_marker.matrix());
    }
    ASSERT_EQ(a.dataset.groundtruth_trajectory->size(), b.dataset.groundtruth_trajectory->size());
    for (size_t k = 0; k < a.dataset.groundtruth_trajectory->size(); ++k) {
      EXPECT_EQ((*a.dataset.groundtruth_trajectory)[k].T.matrix(),
                (*b.dataset.groundtruth_trajectory)[k].T.matrix());
    }
    EXPECT_NE(a.dataset.odometry.back().T.translation(), b.dataset.odometry.back().T.translation())
        << scenario.name;
    const std::vector<double> ra = CornerResiduals(a), rb = CornerResiduals(b);
    ASSERT_FALSE(ra.empty());
    EXPECT_NE(ra.front(), rb.front()) << scenario.name;
  }
}

TEST(SimulatorTest, NoiselessCornersAreExactProjections) {
  for (const ScenarioInfo& scenario : Scenarios()) {
    const SimResult r = RunSim(scenario.name, kNoiseless, 3);
    const std::vector<double> residuals = CornerResiduals(r);
    ASSERT_GT(residuals.size(), 1000u) << scenario.name;
    for (double e : residuals) ASSERT_EQ(e, 0.0) << scenario.name;
    EXPECT_EQ(r.stats.missed, 0) << scenario.name;
  }
}

TEST(SimulatorTest, CornerNoiseHasTheConfiguredSigma) {
  for (double sigma_px : {0.5, 2.0}) {
    const SimResult r = RunSim("ceiling-grid", {"detect.pixel_sigma_px=" + std::to_string(sigma_px)}, 4);
    const std::vector<double> e = CornerResiduals(r);
    double sum = 0.0, sum_sq = 0.0;
    for (double x : e) {
      sum += x;
      sum_sq += x * x;
    }
    const double n = static_cast<double>(e.size());
    ASSERT_GT(n, 5000.0);
    const double mean = sum / n, sigma = std::sqrt(sum_sq / n - mean * mean);
    // Standard errors: sigma / sqrt(n) for the mean, sigma / sqrt(2 n) for sigma; 5 of them.
    EXPECT_NEAR(mean, 0.0, 5.0 * sigma_px / std::sqrt(n));
    EXPECT_NEAR(sigma, sigma_px, 5.0 * sigma_px / std::sqrt(2.0 * n));
    EXPECT_EQ(r.dataset.cameras.at("up").pixel_sigma, sigma_px);
  }
}

TEST(SimulatorTest, RangeAngleAndImageLimitsHold) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"corridor", {}},
      {"rooms", {"detect.max_range_m=1.8", "detect.max_angle_deg=30"}},
      {"warehouse-drone", {"detect.min_range_m=1.2", "detect.max_range_m=2.0", "detect.max_angle_deg=40"}}};
  for (const auto& [scenario, sets] : cases) {
    std::vector<std::string> all = sets;
    all.push_back("detect.pixel_sigma_px=1");
    const SimResult r = RunSim(scenario, all, 5);
    ParamSet params = ScenarioParams(scenario);
    for (const std::string& s : sets) params.SetAssignment(s);
    const double min_range = params.Double("detect.min_range_m"),
                 max_range = params.Double("detect.max_range_m");
    const double max_angle = params.Double("detect.max_angle_deg");
    long count = 0;
    ForEachObservation(r, [&](const DetectionFrame& frame, const MarkerObservation& obs,
                              const SE3d& T_world_camera, const MapMarker& truth) {
      const Eigen::Vector3d to_camera = T_world_camera.translation() - truth.T_world_marker.translation();
      const Eigen::Vector3d normal = truth.T_world_marker.rotation() * Eigen::Vector3d::UnitZ();
      EXPECT_GE(to_camera.norm(), min_range);
      EXPECT_LE(to_camera.norm(), max_range);
      EXPECT_LE(std::acos(normal.dot(to_camera.normalized())) * 180.0 / M_PI, max_angle + 1e-9);
      for (const Eigen::Vector2d& px : obs.corners_px)
        EXPECT_TRUE(r.dataset.cameras.at(frame.camera).InImage(px));
      ++count;
    });
    EXPECT_GT(count, 50) << scenario;
  }
}

TEST(SimulatorTest, CorridorSpacingSetsTheNumberOfCodes) {
  const long d1 = RunSim("corridor", {"place.spacing_m=1"}, 1).stats.markers;
  const long d2 = RunSim("corridor", {"place.spacing_m=2"}, 1).stats.markers;
  const long d4 = RunSim("corridor", {"place.spacing_m=4"}, 1).stats.markers;
  // Faces of 10.8, 6.8, 13.2 and 9.2 m, two of each: codes at d/2, 3d/2, ...
  EXPECT_EQ(d1, 2 * (11 + 7 + 13 + 9));
  EXPECT_EQ(d2, 2 * (5 + 3 + 7 + 5));
  EXPECT_EQ(d4, 2 * (3 + 2 + 3 + 2));
}

// markers.json gives every code's size; only the anchors also give their (fixed, true) pose.
TEST(SimulatorTest, KnownMarkersListEverySizeAndOnlyAnchorPoses) {
  const SimResult r = RunSim("corridor", {"place.anchors=2"}, 1);
  ASSERT_TRUE(r.dataset.known_markers.has_value());
  ASSERT_TRUE(r.dataset.groundtruth_markers.has_value());
  EXPECT_EQ(r.dataset.known_markers->markers.size(), r.dataset.groundtruth_markers->markers.size());
  int anchors = 0;
  for (const MapMarker& known : r.dataset.known_markers->markers) {
    const MapMarker* truth = r.dataset.groundtruth_markers->Find(known.key);
    ASSERT_NE(truth, nullptr) << known.key.ToString();
    EXPECT_DOUBLE_EQ(known.size_m, truth->size_m);
    EXPECT_EQ(known.fixed, known.has_pose);
    if (known.has_pose) {
      ++anchors;
      EXPECT_LT((known.T_world_marker.translation() - truth->T_world_marker.translation()).norm(), 1e-12);
    }
  }
  EXPECT_EQ(anchors, 2);
}

// Rooms: 3 rooms of 4 m in a row (x in [0, 12]), doors at y in [1.5, 2.5] on x = 4 and 8; the
// unconnected room is x in [16, 20]. Wide limits so that only walls stop the view.
TEST(SimulatorTest, RoomsHaveExactlyTheIntendedComponents) {
  const SimResult r =
      RunSim("rooms", {"detect.max_range_m=30", "detect.max_angle_deg=85", "detect.misdecode_fraction=0"}, 6);
  auto room_of = [](double x) { return static_cast<int>(std::floor(x / 4.0)); };
  std::set<MarkerKey> before, after;
  const auto poses = PosesByStamp(*r.dataset.groundtruth_trajectory);
  long through_door = 0;
  ForEachObservation(r, [&](const DetectionFrame& frame, const MarkerObservation& obs,
                            const SE3d& T_world_camera, const MapMarker& truth) {
    const Eigen::Vector3d c = T_world_camera.translation(), m = truth.T_world_marker.translation();
    const int camera_room = room_of(c.x());
    (camera_room >= 4 ? after : before).insert(obs.key);
    // Every shared wall crossed on the way must be crossed inside its door.
    for (double wall_x : {4.0, 8.0}) {
      if ((c.x() - wall_x) * (m.x() - wall_x) >= 0.0) continue;
      const double s = (wall_x - c.x()) / (m.x() - c.x());
      const double y = c.y() + s * (m.y() - c.y());
      EXPECT_GT(y, 1.5) << frame.stamp_s << " " << obs.key.ToString();
      EXPECT_LT(y, 2.5) << frame.stamp_s << " " << obs.key.ToString();
      ++through_door;
    }
    (void)poses;
  });
  for (const MarkerKey& key : after) EXPECT_EQ(before.count(key), 0u) << key.ToString();
  EXPECT_GT(after.size(), 4u);
  EXPECT_GT(before.size(), 12u);
  EXPECT_GT(through_door, 0);  // the doors are really open
  // Ground-truth components follow: 0 for the connected rooms, 1 for the unconnected one.
  for (const MapMarker& m : r.dataset.groundtruth_markers->markers) {
    if (!m.component) continue;
    const int room = room_of(m.T_world_marker.translation().x());
    EXPECT_EQ(*m.component, room >= 4 ? 1 : 0) << m.key.ToString();
  }
  // The robot is carried: a gap in the stamps, and odometry restarts at identity.
  const Trajectory& odometry = r.dataset.odometry;
  size_t jumps = 0;
  for (size_t k = 1; k < odometry.size(); ++k) {
    if (odometry[k].stamp_s - odometry[k - 1].stamp_s > 1.0) {
      ++jumps;
      EXPECT_EQ(odometry[k].T.translation().norm(), 0.0);
    }
  }
  EXPECT_EQ(jumps, 1u);
}

TEST(SimulatorTest, DroneFloorPayloadsParseToTheirTruePositions) {
  const SimResult r = RunSim("warehouse-drone", {}, 1);
  ASSERT_TRUE(r.dataset.config.payload.has_value());
  const PayloadSpec& spec = *r.dataset.config.payload;
  const std::regex pattern(spec.pattern);
  ASSERT_EQ(spec.fields, (std::vector<std::string>{"kind", "x", "y"}));
  int floor = 0, load = 0;
  for (const MapMarker& m : r.dataset.groundtruth_markers->markers) {
    std::smatch match;
    if (std::regex_match(m.key.id, match, pattern)) {
      ++floor;
      EXPECT_EQ(match[1].str(), "0");
      EXPECT_NEAR(std::stod(match[2].str()), m.T_world_marker.translation().x(), 1e-12) << m.key.id;
      EXPECT_NEAR(std::stod(match[3].str()), m.T_world_marker.translation().y(), 1e-12) << m.key.id;
      EXPECT_EQ(m.T_world_marker.translation().z(), 0.0);
      EXPECT_NEAR((m.T_world_marker.rotation() * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-12);  // faces up
    } else {
      ++load;
      EXPECT_EQ(m.key.id.substr(0, 2), "1/") << m.key.id;
    }
  }
  EXPECT_EQ(floor, 32);  // 2 aisles x 2 rows x 8
  EXPECT_EQ(load, 64);   // 4 faces x 8 bays x 2 levels
  EXPECT_EQ(r.dataset.config.motion, MotionModel::kFree);
}

TEST(SimulatorTest, MisdecodeFractionIsRespected) {
  const double fraction = 0.1;
  const SimResult r = RunSim("corridor", {"detect.misdecode_fraction=0.1", "detect.pixel_sigma_px=0.5"}, 8);
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : r.dataset.cameras) cameras.emplace(name, Camera(info));
  const auto poses = PosesByStamp(*r.dataset.groundtruth_trajectory);
  long wrong = 0, total = 0;
  for (const DetectionFrame& frame : r.dataset.detections) {
    const SE3d T_camera_world =
        (poses.at(frame.stamp_s) * r.dataset.cameras.at(frame.camera).T_robot_camera).inverse();
    for (const MarkerObservation& obs : frame.markers) {
      // The code whose true corners are nearest the observed ones produced it.
      double best = 1e18;
      const MapMarker* producer = nullptr;
      for (const MapMarker& m : r.dataset.groundtruth_markers->markers) {
        const auto corners = MarkerCorners(m.size_m);
        double d = 0.0;
        for (int c = 0; c < 4 && d < best; ++c) {
          const Eigen::Vector3d p = T_camera_world * (m.T_world_marker * corners[c]);
          const auto px = p.z() > 0.01 ? cameras.at(frame.camera).Project(p) : std::nullopt;
          d += px ? (*px - obs.corners_px[c]).squaredNorm() : 1e18;
        }
        if (d < best) {
          best = d;
          producer = &m;
        }
      }
      ASSERT_NE(producer, nullptr);
      ++total;
      if (producer->key != obs.key) ++wrong;
    }
  }
  ASSERT_GT(total, 1000);
  const double sd = std::sqrt(fraction * (1 - fraction) / total);
  EXPECT_NEAR(static_cast<double>(wrong) / total, fraction, 4.0 * sd) << wrong << " of " << total;
  EXPECT_EQ(wrong, r.stats.misdecoded);
}

// RMS position error of odometry placed at the true start pose.
double OdometryAte(const SimResult& r) {
  const Trajectory& truth = *r.dataset.groundtruth_trajectory;
  const SE3d T_world_odom = truth.front().T * r.dataset.odometry.front().T.inverse();
  double sum_sq = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    sum_sq += (T_world_odom * r.dataset.odometry[k].T.translation() - truth[k].T.translation()).squaredNorm();
  }
  return std::sqrt(sum_sq / truth.size());
}

TEST(SimulatorTest, WheelOdometryAteGrowsWithTheSystematicError) {
  std::vector<double> ate;
  for (double e : {0.0, 0.001, 0.004}) {
    const std::string left = "odometry.wheel_radius_error_left=" + std::to_string(e);
    const std::string right = "odometry.wheel_radius_error_right=" + std::to_string(-e);
    ate.push_back(OdometryAte(RunSim("corridor", {left, right, "odometry.track_width_error=0"}, 9)));
  }
  EXPECT_LT(ate[0], 0.2);
  EXPECT_GT(ate[1], 3.0 * ate[0]);
  EXPECT_GT(ate[2], 2.0 * ate[1]);
  const double exact =
      OdometryAte(RunSim("corridor",
                         {"odometry.trans_per_m=0", "odometry.rot_per_rad=0", "odometry.track_width_error=0",
                          "odometry.wheel_radius_error_left=0", "odometry.wheel_radius_error_right=0"},
                         9));
  EXPECT_LT(exact, 1e-9);
}

TEST(SimulatorTest, VisualOdometryAteGrowsWithScaleAndYawDrift) {
  std::vector<double> ate;
  for (double e : {0.0, 0.02, 0.08}) {
    ate.push_back(OdometryAte(RunSim("warehouse-drone",
                                     {"odometry.scale_error=" + std::to_string(e),
                                      "odometry.yaw_drift_deg_per_m=" + std::to_string(10 * e)},
                                     9)));
  }
  EXPECT_GT(ate[1], 1.5 * ate[0]);
  EXPECT_GT(ate[2], 2.0 * ate[1]);
}

// dataset.yaml's odometry_sigma states the per-step noise: increments divided by
// (trans_per_m * distance) and (rot_per_rad * angle) are standard normal.
TEST(SimulatorTest, WheelOdometryNoiseMatchesOdometrySigma) {
  const SimResult r =
      RunSim("rooms",
             {"odometry.wheel_radius_error_left=0", "odometry.wheel_radius_error_right=0",
              "odometry.track_width_error=0", "odometry.trans_per_m=0.05", "odometry.rot_per_rad=0.03"},
             10);
  ASSERT_TRUE(r.dataset.config.odometry_sigma.has_value());
  const OdometrySigma sigma = *r.dataset.config.odometry_sigma;
  EXPECT_EQ(sigma.trans_per_m, 0.05);
  EXPECT_EQ(sigma.rot_per_rad, 0.03);
  const Trajectory& truth = *r.dataset.groundtruth_trajectory;
  const Trajectory& odometry = r.dataset.odometry;
  std::vector<double> z_trans, z_rot;
  for (size_t k = 1; k < truth.size(); ++k) {
    if (odometry[k].stamp_s - odometry[k - 1].stamp_s > 1.0) continue;  // the carry
    const SE2d true_step = SE2d::FromSE3(truth[k - 1].T).inverse() * SE2d::FromSE3(truth[k].T);
    const SE2d odom_step = SE2d::FromSE3(odometry[k - 1].T).inverse() * SE2d::FromSE3(odometry[k].T);
    const double distance = true_step.translation().norm(), angle = std::abs(true_step.theta());
    if (distance > 1e-6) {
      z_trans.push_back((odom_step.x() - true_step.x()) / (sigma.trans_per_m * distance));
      z_trans.push_back((odom_step.y() - true_step.y()) / (sigma.trans_per_m * distance));
    }
    if (angle > 1e-6)
      z_rot.push_back(WrapAngle(odom_step.theta() - true_step.theta()) / (sigma.rot_per_rad * angle));
  }
  for (const auto* z : {&z_trans, &z_rot}) {
    ASSERT_GT(z->size(), 500u);
    double sum_sq = 0.0;
    for (double x : *z) sum_sq += x * x;
    EXPECT_NEAR(std::sqrt(sum_sq / z->size()), 1.0, 5.0 / std::sqrt(2.0 * z->size()));
  }
}

TEST(SimulatorTest, VisualOdometryNoiseMatchesOdometrySigma) {
  const SimResult r = RunSim("warehouse-drone",
                             {"odometry.scale_error=0", "odometry.yaw_drift_deg_per_m=0",
                              "odometry.trans_per_m=0.04", "odometry.rot_per_rad=0.05"},
                             10);
  const Trajectory& truth = *r.dataset.groundtruth_trajectory;
  const Trajectory& odometry = r.dataset.odometry;
  std::vector<double> z_trans, z_rot;
  for (size_t k = 1; k < truth.size(); ++k) {
    const SE3d true_step = truth[k - 1].T.inverse() * truth[k].T;
    const SE3d odom_step = odometry[k - 1].T.inverse() * odometry[k].T;
    const double distance = true_step.translation().norm();
    const double angle = LogSO3(true_step.rotation()).norm();
    if (distance > 1e-6) {
      const Eigen::Vector3d e = (odom_step.translation() - true_step.translation()) / (0.04 * distance);
      z_trans.insert(z_trans.end(), {e.x(), e.y(), e.z()});
    }
    if (angle > 1e-6) {
      const Eigen::Vector3d e =
          LogSO3(true_step.rotation().conjugate() * odom_step.rotation()) / (0.05 * angle);
      z_rot.insert(z_rot.end(), {e.x(), e.y(), e.z()});
    }
  }
  for (const auto* z : {&z_trans, &z_rot}) {
    ASSERT_GT(z->size(), 1000u);
    double sum_sq = 0.0;
    for (double x : *z) sum_sq += x * x;
    EXPECT_NEAR(std::sqrt(sum_sq / z->size()), 1.0, 5.0 / std::sqrt(2.0 * z->size()));
  }
}

TEST(SimulatorTest, DroneFloorRowOffsetZeroGivesOneRowPerAisle) {
  const SimResult r = RunSim("warehouse-drone", {"place.floor_row_offset_m=0"}, 1);
  int floor = 0;
  for (const MapMarker& m : r.dataset.groundtruth_markers->markers) floor += m.key.id.rfind("0/", 0) == 0;
  EXPECT_EQ(floor, 16);  // 2 aisles x 8
}

TEST(SimulatorTest, InconsistentParametersAreRejected) {
  EXPECT_THROW(RunSim("corridor", {"rate.camera_hz=7"}, 1), std::invalid_argument);
  EXPECT_THROW(RunSim("corridor", {"detect.min_range_m=2", "detect.max_range_m=1"}, 1),
               std::invalid_argument);
  EXPECT_THROW(RunSim("corridor", {"place.corridor_width_m=9"}, 1), std::invalid_argument);
  EXPECT_THROW(RunSim("ceiling-grid", {"place.camera_height_m=3"}, 1), std::invalid_argument);
}

}  // namespace
}  // namespace waymark::sim
