#include "online/motion_model.h"

#include <gtest/gtest.h>

#include <random>

#include "geometry/camera.h"
#include "geometry/odometry_noise.h"
#include "online/ekf_state.h"
#include "online/localizer.h"
#include "online/marker_measurement.h"
#include "tests/online/jacobian_check.h"
#include "tests/test_cameras.h"

namespace waymark {
namespace {

using testing::NumericJacobian;

// Wraps the last entry (yaw) of a difference vector.
Eigen::VectorXd WrapLast(Eigen::VectorXd v) {
  v(v.size() - 1) = WrapAngle(v(v.size() - 1));
  return v;
}

constexpr double kTolerance = 1e-7;

TEST(MotionModelTest, PlanarIncrementJacobiansMatchCentralDifferences) {
  const OdometryNoise noise;
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(1.0, -2.0, 0.3), Eigen::Vector3d(-4.0, 0.5, 3.0)}) {
    const Eigen::Vector3d u(0.07, -0.02, 0.05);
    const MotionPrediction p = PredictPlanarIncrement(x, SE2d(u.x(), u.y(), u.z()), noise);
    const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
      return PredictPlanarIncrement(xx, SE2d(u.x(), u.y(), u.z()), noise).mean;
    };
    const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
      return PredictPlanarIncrement(x, SE2d(uu(0), uu(1), uu(2)), noise).mean;
    };
    EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
    EXPECT_LT((p.G - NumericJacobian(f_u, u, 1e-6, WrapLast)).norm(), kTolerance);
  }
}

TEST(MotionModelTest, UnicycleMatchesSeed000AndItsJacobians) {
  const OdometryNoise noise;
  const Eigen::Vector3d x(0.5, 1.5, -2.0);
  const double v = 0.4, omega = 0.6, dt = 0.05;
  const MotionPrediction p = PredictUnicycle(x, v, omega, dt, noise);
  // [Bach], eq. (6).
  EXPECT_NEAR(p.mean(0), x(0) + v * dt * std::cos(x(2) + omega * dt / 2), 1e-15);
  EXPECT_NEAR(p.mean(1), x(1) + v * dt * std::sin(x(2) + omega * dt / 2), 1e-15);
  EXPECT_NEAR(p.mean(2), x(2) + omega * dt, 1e-15);
  const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
    return PredictUnicycle(xx, v, omega, dt, noise).mean;
  };
  // u = [d, a] = [v dt, omega dt].
  const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
    return PredictUnicycle(x, uu(0) / dt, uu(1) / dt, dt, noise).mean;
  };
  EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
  EXPECT_LT((p.G - NumericJacobian(f_u, Eigen::Vector2d(v * dt, omega * dt), 1e-7, WrapLast)).norm(),
            kTolerance);
}

TEST(MotionModelTest, FreeIncrementJacobiansMatchCentralDifferences) {
  const OdometryNoise noise;
  const Eigen::Matrix3d R_level =
      (Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Eigen::Vector4d x(1.0, 2.0, 1.5, 0.8);
  const SE3d increment(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.2, -0.3, 1.0).normalized())),
      Eigen::Vector3d(0.1, 0.02, -0.03));
  const MotionPrediction p = PredictFreeIncrement(x, R_level, increment, noise);
  const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
    return PredictFreeIncrement(xx, R_level, increment, noise).mean;
  };
  // u = [dt, dphi]: increment (dR Exp(dphi), dt).
  const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
    const SE3d perturbed(increment.rotation() * ExpSO3(uu.tail<3>()), increment.translation() + uu.head<3>());
    return PredictFreeIncrement(x, R_level, perturbed, noise).mean;
  };
  EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
  EXPECT_LT((p.G - NumericJacobian(f_u, Eigen::VectorXd::Zero(6), 1e-6, WrapLast)).norm(), kTolerance);
  // The mean is the composition T_world_robot * increment.
  const SE3d T_world_robot(
      Eigen::Matrix3d(Eigen::AngleAxisd(x(3), Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_level),
      Eigen::Vector3d(x.head<3>()));
  const SE3d composed = T_world_robot * increment;
  EXPECT_LT((p.mean.head<3>() - composed.translation()).norm(), 1e-12);
  EXPECT_NEAR(p.mean(3), composed.yaw(), 1e-12);
}

TEST(MotionModelTest, NoiseScalesWithTravelAndHasAFloor) {
  OdometryNoise noise;
  noise.sigma = {0.05, 0.1};
  noise.floor_trans_m = 1e-3;
  noise.floor_rot_rad = 2e-3;
  noise.heading_per_sqrt_m = 0.0;
  const MotionPrediction still = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0, 0, 0), noise);
  EXPECT_NEAR(still.Qu(0, 0), 1e-6, 1e-18);
  EXPECT_NEAR(still.Qu(2, 2), 4e-6, 1e-18);
  const MotionPrediction moved = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0.3, 0.4, -0.5), noise);
  EXPECT_NEAR(std::sqrt(moved.Qu(0, 0)), 0.05 * 0.5 + 1e-3, 1e-12);
  EXPECT_NEAR(std::sqrt(moved.Qu(2, 2)), 0.1 * 0.5 + 2e-3, 1e-12);
  std::string why;
  noise.floor_rot_rad = 0.0;
  EXPECT_FALSE(noise.Check(&why));
  EXPECT_NE(why.find("floor"), std::string::npos);
}

// The heading random walk adds heading_per_sqrt_m^2 * distance to the heading variance of
// every increment (and of the unicycle), so the heading variance after D metres is the same
// at any odometry rate.
TEST(MotionModelTest, HeadingWalkGrowsWithDistanceNotRate) {
  OdometryNoise noise;
  noise.sigma = {0.0, 0.0};
  noise.heading_per_sqrt_m = 0.01;
  const double floor_variance = noise.floor_rot_rad * noise.floor_rot_rad;
  const MotionPrediction step = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0.3, 0.4, 0.0), noise);
  EXPECT_NEAR(step.Qu(2, 2), 1e-4 * 0.5 + floor_variance, 1e-15);
  const MotionPrediction unicycle = PredictUnicycle(Eigen::Vector3d::Zero(), 0.5, 0.0, 2.0, noise);
  EXPECT_NEAR(unicycle.Qu(1, 1), 1e-4 * 1.0 + floor_variance, 1e-15);
  for (int steps : {10, 100}) {
    noise.floor_rot_rad = 1e-12;
    Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
    for (int k = 0; k < steps; ++k) {
      const MotionPrediction p =
          PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(4.0 / steps, 0.0, 0.0), noise);
      P = p.F * P * p.F.transpose() + p.G * p.Qu * p.G.transpose();
    }
    EXPECT_NEAR(P(2, 2), 1e-4 * 4.0, 1e-12) << steps << " steps";
  }
  std::string why;
  noise.heading_per_sqrt_m = -1.0;
  EXPECT_FALSE(noise.Check(&why));
  EXPECT_NE(why.find("heading_per_sqrt_m"), std::string::npos);
}

// odometry_sigma's random-walk terms: the process noise they add over a stretch of T seconds
// and L metres is the same whatever the odometry rate, and equals what the map build gives an
// odometry link over that stretch (OdometryRandomWalk, geometry/odometry_noise.h).
TEST(MotionModelTest, RandomWalkProcessNoiseIsRateIndependentAndMatchesTheMapLinks) {
  OdometryNoise noise;
  noise.sigma = {0.0, 0.0};
  noise.sigma.trans_per_sqrt_s = 0.02;
  noise.sigma.rot_per_sqrt_s = 0.003;
  noise.sigma.trans_per_sqrt_m = 0.01;
  noise.sigma.rot_per_sqrt_m = 0.004;
  noise.floor_trans_m = noise.floor_rot_rad = 1e-12;
  const double duration_s = 8.0, path_m = 4.0;
  const OdometryWalkVariance link = OdometryRandomWalk(noise.sigma, duration_s, path_m);
  EXPECT_NEAR(link.translation, 0.02 * 0.02 * 8.0 + 0.01 * 0.01 * 4.0, 1e-15);
  EXPECT_NEAR(link.rotation, 0.003 * 0.003 * 8.0 + 0.004 * 0.004 * 4.0, 1e-15);
  for (int steps : {10, 200}) {
    const double dt = duration_s / steps;
    Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
    Eigen::Matrix4d P_free = Eigen::Matrix4d::Zero();
    OdometryTilt tilt(1e-9);
    for (int k = 0; k < steps; ++k) {
      const SE2d step(path_m / steps, 0.0, 0.0);
      const MotionPrediction p = PredictPlanarIncrement(Eigen::Vector3d::Zero(), step, noise, dt);
      P = p.F * P * p.F.transpose() + p.G * p.Qu * p.G.transpose();
      // The free model, straight up (no lever of the heading on the position): every axis.
      const SE3d up(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, path_m / steps));
      const MotionPrediction f =
          PredictFreeIncrement(Eigen::Vector4d::Zero(), Eigen::Matrix3d::Identity(), up, noise, dt);
      P_free = f.F * P_free * f.F.transpose() + f.G * f.Qu * f.G.transpose();
      tilt.Propagate(up, noise, dt);
    }
    EXPECT_NEAR(P(0, 0), link.translation, 1e-12) << steps;  // along the track: no heading lever
    EXPECT_NEAR(P(2, 2), link.rotation, 1e-12) << steps;
    for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(P_free(axis, axis), link.translation, 1e-12) << steps;
    EXPECT_NEAR(P_free(3, 3), link.rotation, 1e-12) << steps;
    EXPECT_NEAR(tilt.covariance()(0, 0), link.rotation, 1e-12) << steps;
  }
  // The unicycle: the same walk over its own dt.
  const MotionPrediction unicycle = PredictUnicycle(Eigen::Vector3d::Zero(), 0.5, 0.0, 2.0, noise);
  const OdometryWalkVariance one = OdometryRandomWalk(noise.sigma, 2.0, 1.0);
  EXPECT_NEAR(unicycle.Qu(0, 0), one.translation, 1e-12);
  EXPECT_NEAR(unicycle.Qu(1, 1), one.rotation, 1e-12);
  // Without dt (the default 0) only the per-metre walk is left.
  const MotionPrediction no_dt = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(1.0, 0.0, 0.0), noise);
  EXPECT_NEAR(no_dt.Qu(1, 1), 0.01 * 0.01 * 1.0, 1e-12);
  std::string why;
  noise.sigma.rot_per_sqrt_s = -1.0;
  EXPECT_FALSE(noise.Check(&why));
  EXPECT_NE(why.find("random-walk"), std::string::npos);
}

// The heading walk stated in dataset.yaml (rot_per_sqrt_m) replaces the default allowance.
TEST(MotionModelTest, StatedHeadingWalkReplacesTheDefault) {
  OdometryNoise noise;
  noise.sigma = {0.0, 0.0};
  noise.floor_rot_rad = 1e-12;
  const double by_default =
      PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(1.0, 0.0, 0.0), noise).Qu(2, 2);
  EXPECT_NEAR(by_default, noise.heading_per_sqrt_m * noise.heading_per_sqrt_m, 1e-15);
  noise.sigma.rot_per_sqrt_m = 0.02;
  const double stated = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(1.0, 0.0, 0.0), noise).Qu(2, 2);
  EXPECT_NEAR(stated, 0.02 * 0.02, 1e-15);
}

Eigen::Matrix3d RollPitch(double roll_rad, double pitch_rad) {
  return (Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Matrix3d Yaw(double yaw_rad) {
  return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

TEST(OdometryTiltTest, LevelFromUpAndTangentBasis) {
  for (const auto& [roll, pitch] : {std::pair{0.0, 0.0}, {0.3, -0.2}, {-1.2, 0.7}}) {
    const Eigen::Matrix3d R_level = RollPitch(roll, pitch);
    EXPECT_LT((LevelFromUp(R_level.transpose() * Eigen::Vector3d::UnitZ()) - R_level).norm(), 1e-12);
  }
  for (const Eigen::Vector3d& u :
       {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, -1, 0), Eigen::Vector3d(0.3, -0.5, 0.8).normalized()}) {
    const Eigen::Matrix<double, 3, 2> B = TangentBasis(u);
    EXPECT_LT((B.transpose() * B - Eigen::Matrix2d::Identity()).norm(), 1e-12);
    EXPECT_LT((B.transpose() * u).norm(), 1e-12);
  }
}

// An odometry that started at the identity while the robot was pitched and rolled: its own
// roll and pitch are off by that tilt; the estimate from noisy single-code attitudes recovers it.
TEST(OdometryTiltTest, RecoversTheOdometryFramesTiltFromCodeAttitudes) {
  const Eigen::Matrix3d R_world_odom = Yaw(1.2) * RollPitch(-0.02, 0.03);
  const double sigma_rad = 0.01;
  const Eigen::Matrix3d covariance_phi = Eigen::Matrix3d::Identity() * sigma_rad * sigma_rad;
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, sigma_rad);
  OdometryTilt tilt;
  OdometryNoise noise;
  double before_deg = 0.0, after_deg = 0.0;
  for (int k = 0; k < 400; ++k) {
    const Eigen::Matrix3d R_world_robot =
        Yaw(0.01 * k) * RollPitch(0.03 * std::sin(0.1 * k), 0.02 * std::cos(0.07 * k));
    const Eigen::Matrix3d R_odom_robot = R_world_odom.transpose() * R_world_robot;
    tilt.Propagate(SE3d(), noise);
    const Eigen::Matrix3d R_code =
        ExpSO3(Eigen::Vector3d(normal(rng), normal(rng), normal(rng))) * R_world_robot;
    EXPECT_TRUE(tilt.Update(R_odom_robot, R_code, covariance_phi));
    const Eigen::Matrix3d truth = LevelRotation(R_world_robot);
    before_deg = RotationAngleBetween(SE3d(LevelRotation(R_odom_robot), Eigen::Vector3d::Zero()),
                                      SE3d(truth, Eigen::Vector3d::Zero())) *
                 180.0 / M_PI;
    after_deg = RotationAngleBetween(SE3d(tilt.Level(R_odom_robot), Eigen::Vector3d::Zero()),
                                     SE3d(truth, Eigen::Vector3d::Zero())) *
                180.0 / M_PI;
  }
  EXPECT_GT(before_deg, 1.0);  // the odometry's own attitude is off by the start tilt
  EXPECT_LT(after_deg, 0.1);
  // The estimate's covariance tells its error: sigma / sqrt(400) per axis plus the random walk.
  const Eigen::Vector3d up_true = R_world_odom.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector2d d = TangentBasis(tilt.up_odom()).transpose() * (up_true - tilt.up_odom());
  EXPECT_LT(d.dot(tilt.covariance().llt().solve(d)), 13.8);  // chi2(2) 0.999
  EXPECT_LT(std::sqrt(tilt.covariance()(0, 0)), 2.0 * sigma_rad / std::sqrt(400.0) + 3e-3);
  EXPECT_EQ(tilt.updates(), 400);
}

TEST(OdometryTiltTest, GatesAFlippedAttitudeAndPropagatesTheRotationNoise) {
  OdometryTilt tilt(0.01);
  const Eigen::Matrix3d covariance_phi = Eigen::Matrix3d::Identity() * 1e-4;
  const Eigen::Matrix3d flipped = RollPitch(0.5, 0.0);  // a code pose 29 deg off (IPPE's other solution)
  EXPECT_FALSE(tilt.Update(Eigen::Matrix3d::Identity(), flipped, covariance_phi));
  EXPECT_EQ(tilt.up_odom(), Eigen::Vector3d::UnitZ());
  EXPECT_FALSE(tilt.Update(Eigen::Matrix3d::Identity(), flipped, Eigen::Matrix3d::Constant(NAN)));
  OdometryNoise noise;
  noise.sigma = {0.0, 0.1};
  noise.floor_rot_rad = 1e-3;
  const Eigen::Matrix2d before = tilt.covariance();
  tilt.Propagate(
      SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ())), Eigen::Vector3d::Zero()),
      noise);
  const double sigma_rot = 0.1 * 0.2 + 1e-3;
  EXPECT_LT((tilt.covariance() - before - Eigen::Matrix2d::Identity() * sigma_rot * sigma_rot).norm(), 1e-15);
}

// A drone at 1.2 m over a grid of floor codes with exact odometry increments whose frame is
// tilted (it started at the identity while the drone was pitched 2 deg and rolled -1 deg): with
// the true map, the localizer's position must not inherit the tilt (h tan(2 deg) = 4 cm).
TEST(OdometryTiltTest, LocalizerOverFloorCodesIsNotTiltedByTheOdometryFrame) {
  CameraInfo down = testing::IdealPinholeInfo("down", 640, 480, 380.0);
  down.pixel_sigma = 0.5;
  Eigen::Matrix3d R_robot_camera;  // camera z down (robot -z), camera x along robot -y
  R_robot_camera << 0, -1, 0, -1, 0, 0, 0, 0, -1;
  down.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d::Zero());
  MarkerMap map;
  for (int i = -2; i <= 12; ++i) {
    for (int j = -1; j <= 1; ++j) {
      MapMarker marker;
      marker.key = {"qr", "0/" + std::to_string(i) + "/" + std::to_string(j)};
      marker.size_m = 0.15;
      marker.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.7 * i, 0.7 * j, 0.0));
      map.markers.push_back(marker);
    }
  }
  LocalizerOptions options;
  options.motion = MotionModel::kFree;
  options.loose_noise = Eigen::Vector4d::Constant(0.001);
  Localizer localizer(options, map, {down});
  const Camera camera(down);
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 0.5);
  const auto truth_at = [](int k) {
    const double t = 0.05 * k;
    return SE3d(Eigen::Quaterniond(Yaw(0.1 + 0.02 * t) * RollPitch(-0.0175 + 0.02 * std::sin(1.3 * t),
                                                                   0.035 + 0.02 * std::sin(2.1 * t + 1.0))),
                Eigen::Vector3d(0.3 * t, 0.1 * std::sin(0.5 * t), 1.2 + 0.05 * std::sin(0.8 * t)));
  };
  const SE3d T_odom_world = truth_at(0).inverse();  // the odometry starts at the identity
  double sum_error_m = 0.0;
  int count = 0;
  for (int k = 0; k <= 500; ++k) {
    const SE3d T_world_robot = truth_at(k);
    localizer.AddOdometry(0.05 * k, T_odom_world * T_world_robot);
    if (k % 2 != 0) continue;
    DetectionFrame frame;
    frame.stamp_s = 0.05 * k;
    frame.camera = "down";
    const SE3d T_camera_world = (T_world_robot * down.T_robot_camera).inverse();
    for (const MapMarker& marker : map.markers) {
      MarkerObservation observation;
      observation.key = marker.key;
      bool visible = true;
      const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(marker.size_m);
      for (int c = 0; c < 4 && visible; ++c) {
        const auto px = camera.Project(T_camera_world * marker.T_world_marker * corners[c]);
        visible = px && down.InImage(*px);
        if (visible) observation.corners_px[c] = *px + Eigen::Vector2d(normal(rng), normal(rng));
      }
      if (visible) frame.markers.push_back(observation);
    }
    localizer.AddDetections(frame);
    const PoseOutput output = localizer.Output();
    if (k < 100 || !output.T_world_robot) continue;  // the first 5 s: the tilt estimate settles
    sum_error_m += (output.T_world_robot->translation() - T_world_robot.translation()).norm();
    ++count;
  }
  ASSERT_GT(count, 150);
  EXPECT_LT(sum_error_m / count, 0.005);
}

}  // namespace
}  // namespace waymark
