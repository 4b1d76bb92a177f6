// Tests of geometry/camera.h against OpenCV, central differences, Ceres Jets, and itself
// (project o unproject). The two calibrations are real ones, typed in from
// /work/shared/data/tagslam: tagslam-test16 cam0 (radtan, strong barrel distortion) and
// tagslam-test22 cam0 (RealSense T265 fisheye, equidistant). The equisolid model (no OpenCV
// counterpart) is checked against its closed form r = 2 f sin(theta/2) on [Seki]'s camera,
// and with a distortion polynomial.
#include "geometry/camera.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <random>
#include <vector>

#include "tests/test_cameras.h"

namespace waymark {
namespace {

CameraInfo RadtanInfo() { return testing::TagslamRadtanInfo(); }

// The dataset's yaml says width 800, height 848, but the principal point (421, 401) and the
// T265 sensor (848 x 800) say the image is 848 wide; the grid below covers 848 x 848 so that
// either reading is tested.
CameraInfo FisheyeInfo() { return testing::TagslamFisheyeInfo(); }

CameraInfo EquisolidInfo() { return testing::Seed002EquisolidInfo(); }

// [Seki]'s camera with a distortion polynomial (as a calibration would give).
CameraInfo DistortedEquisolidInfo() {
  CameraInfo info = testing::Seed002EquisolidInfo();
  info.intrinsics = {343.0, 344.1, 641.3, 509.7};
  info.distortion = {0.012, -0.004, 0.0007, -0.0002};
  return info;
}

cv::Matx33d CvK(const CameraInfo& info) {
  const auto& k = info.intrinsics;
  return cv::Matx33d(k[0], 0.0, k[2], 0.0, k[1], k[3], 0.0, 0.0, 1.0);
}

// Random points in front of the camera with normalized radius up to `max_radius`.
std::vector<Eigen::Vector3d> RandomPoints(int n, double max_radius, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> radius(0.0, max_radius), angle(-M_PI, M_PI), depth(0.2, 20.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double r = radius(rng), a = angle(rng), z = depth(rng);
    points.emplace_back(r * std::cos(a) * z, r * std::sin(a) * z, z);
  }
  // Points on and near the optical axis exercise the r -> 0 branch of the fisheye model.
  points.emplace_back(0.0, 0.0, 1.0);
  points.emplace_back(1e-7, -2e-7, 1.0);
  points.emplace_back(3e-5, 2e-5, 0.5);
  return points;
}

TEST(CameraTest, RadtanRoundTripOverWholeImage) {
  const Camera camera(RadtanInfo());
  double worst_px = 0.0;
  int count = 0;
  for (double v = 0.0; v <= camera.height(); v += 4.0) {
    for (double u = 0.0; u <= camera.width(); u += 4.0) {
      const Eigen::Vector2d px(u, v);
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(px);
      ASSERT_TRUE(ray.has_value()) << "pixel " << px.transpose();
      EXPECT_DOUBLE_EQ(ray->z(), 1.0);
      const std::optional<Eigen::Vector2d> back = camera.Project(*ray);
      ASSERT_TRUE(back.has_value()) << "pixel " << px.transpose();
      worst_px = std::max(worst_px, (*back - px).norm());
      ++count;
    }
  }
  EXPECT_GT(count, 80000);
  EXPECT_LE(worst_px, 1e-6);
}

TEST(CameraTest, FisheyeRoundTripOverWholeImage) {
  const Camera camera(FisheyeInfo());
  const auto& k = camera.info().intrinsics;
  // theta_d at the edge of the valid field of view, from a point just inside it.
  const double r_edge = camera.max_normalized_radius() * (1.0 - 1e-9);
  const Eigen::Vector2d px_edge = *camera.Project(Eigen::Vector3d(r_edge, 0.0, 1.0));
  const double theta_d_edge = (px_edge.x() - k[2]) / k[0];
  EXPECT_GT(theta_d_edge, 1.3);  // this lens sees ~80 degrees off-axis
  double worst_px = 0.0;
  int inside = 0, outside = 0;
  for (double v = 0.0; v <= 848.0; v += 3.0) {
    for (double u = 0.0; u <= 848.0; u += 3.0) {
      const Eigen::Vector2d px(u, v);
      const double theta_d = Eigen::Vector2d((u - k[2]) / k[0], (v - k[3]) / k[1]).norm();
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(px);
      if (theta_d > theta_d_edge * (1.0 + 1e-9)) {
        EXPECT_FALSE(ray.has_value()) << "pixel " << px.transpose() << " is outside the field of view";
        ++outside;
        continue;
      }
      if (theta_d > theta_d_edge * (1.0 - 1e-9)) continue;  // on the edge: either answer is right
      ASSERT_TRUE(ray.has_value()) << "pixel " << px.transpose();
      const std::optional<Eigen::Vector2d> back = camera.Project(*ray);
      ASSERT_TRUE(back.has_value()) << "pixel " << px.transpose();
      worst_px = std::max(worst_px, (*back - px).norm());
      ++inside;
    }
  }
  EXPECT_GT(inside, 50000);
  EXPECT_GT(outside, 1000);  // the image corners are beyond 90 degrees
  EXPECT_LE(worst_px, 1e-6);
}

// Every pixel of the image within 90 degrees of the axis comes back from its ray; pixels
// further out (the image corners of [Seki]'s camera) have no ray.
void ExpectFisheyeRoundTrip(const Camera& camera, int min_inside, int min_outside) {
  const auto& k = camera.info().intrinsics;
  const double r_edge = camera.max_normalized_radius() * (1.0 - 1e-9);
  const Eigen::Vector2d px_edge = *camera.Project(Eigen::Vector3d(r_edge, 0.0, 1.0));
  const double rho_edge = (px_edge.x() - k[2]) / k[0];
  double worst_px = 0.0;
  int inside = 0, outside = 0;
  for (double v = 0.0; v <= camera.height(); v += 3.0) {
    for (double u = 0.0; u <= camera.width(); u += 3.0) {
      const Eigen::Vector2d px(u, v);
      const double rho = Eigen::Vector2d((u - k[2]) / k[0], (v - k[3]) / k[1]).norm();
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(px);
      if (rho > rho_edge * (1.0 + 1e-9)) {
        EXPECT_FALSE(ray.has_value()) << "pixel " << px.transpose() << " is outside the field of view";
        ++outside;
        continue;
      }
      if (rho > rho_edge * (1.0 - 1e-9)) continue;  // on the edge: either answer is right
      ASSERT_TRUE(ray.has_value()) << "pixel " << px.transpose();
      const std::optional<Eigen::Vector2d> back = camera.Project(*ray);
      ASSERT_TRUE(back.has_value()) << "pixel " << px.transpose();
      worst_px = std::max(worst_px, (*back - px).norm());
      ++inside;
    }
  }
  EXPECT_GT(inside, min_inside);
  EXPECT_GT(outside, min_outside);
  EXPECT_LE(worst_px, 1e-6);
}

TEST(CameraTest, EquisolidRoundTripOverWholeImage) {
  const Camera ideal(EquisolidInfo());
  // No fold: the ideal lens is used up to 90 degrees (1e-6 rad short).
  EXPECT_NEAR(std::atan(ideal.max_normalized_radius()), 0.5 * M_PI, 1e-5);
  ExpectFisheyeRoundTrip(ideal, 70000, 20000);
  ExpectFisheyeRoundTrip(Camera(DistortedEquisolidInfo()), 70000, 20000);
}

// r = 2 f sin(theta / 2): the ideal model against the closed form in long double, and seed
// 002's lens: its 160 degree field of view is a circle of 441 px radius.
TEST(CameraTest, EquisolidMatchesClosedForm) {
  const Camera camera(EquisolidInfo());
  const double f = camera.info().intrinsics[0];
  for (const Eigen::Vector3d& p : RandomPoints(2000, std::tan(85.0 * M_PI / 180.0), 21)) {
    const long double theta =
        std::atan2(std::hypot(static_cast<long double>(p.x()), p.y()), static_cast<long double>(p.z()));
    const long double r = 2.0L * f * std::sin(theta / 2.0L), a = std::atan2(p.y(), p.x());
    const std::optional<Eigen::Vector2d> px = camera.Project(p);
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR(px->x(), static_cast<double>(640.0L + r * std::cos(a)), 1e-9);
    EXPECT_NEAR(px->y(), static_cast<double>(512.0L + r * std::sin(a)), 1e-9);
  }
  const double theta_80 = 80.0 * M_PI / 180.0;
  const Eigen::Vector2d edge = *camera.Project(Eigen::Vector3d(std::sin(theta_80), 0.0, std::cos(theta_80)));
  EXPECT_NEAR(edge.x() - 640.0, 441.3, 0.1);
  // A ray 80 degrees off-axis comes back from its pixel.
  const std::optional<Eigen::Vector3d> ray = camera.Unproject(edge);
  ASSERT_TRUE(ray.has_value());
  EXPECT_NEAR(std::atan(ray->x()), theta_80, 1e-12);
}

TEST(CameraTest, EquisolidOnAxisJacobianIsFocalOverDepth) {
  const Camera camera(DistortedEquisolidInfo());
  Eigen::Matrix<double, 2, 3> J;
  const std::optional<Eigen::Vector2d> px = camera.Project(Eigen::Vector3d(0.0, 0.0, 2.0), &J);
  ASSERT_TRUE(px.has_value());
  EXPECT_DOUBLE_EQ(px->x(), 641.3);
  EXPECT_DOUBLE_EQ(px->y(), 509.7);
  Eigen::Matrix<double, 2, 3> expected;
  expected << 343.0 / 2.0, 0.0, 0.0, 0.0, 344.1 / 2.0, 0.0;
  EXPECT_LE((J - expected).norm(), 1e-12);
}

// The r -> 0 series of the equisolid scale s(u) = rho / r against the closed form in long
// double, on both sides of the switch, and its slope s'(0) = k1 - 3/8.
TEST(CameraTest, EquisolidSeriesMatchesClosedForm) {
  const std::vector<double> d = DistortedEquisolidInfo().distortion;
  const auto closed_form = [&d](long double u) {
    const long double r = std::sqrt(u), theta = std::atan(r), t2 = theta * theta;
    return 2.0L * std::sin(theta / 2.0L) * (1.0L + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])))) / r;
  };
  for (double u : {1e-14, 1e-11, 1e-9, 0.999e-8, 1.001e-8, 1e-7}) {
    EXPECT_NEAR(EquisolidScale(d.data(), u), static_cast<double>(closed_form(u)), 1e-15) << u;
    const long double h = 1e-3L * u;
    const double slope = static_cast<double>((closed_form(u + h) - closed_form(u - h)) / (2.0L * h));
    using Jet = ceres::Jet<double, 1>;
    const Jet d_jet[4] = {Jet(d[0]), Jet(d[1]), Jet(d[2]), Jet(d[3])};
    const Jet s = EquisolidScale(d_jet, Jet(u, 0));
    if (u >= 1e-9) {  // below, long double differences are noise
      EXPECT_NEAR(s.v(0), slope, 1e-6) << u;
    }
    EXPECT_NEAR(s.v(0), d[0] - 3.0 / 8.0, 1e-6) << u;
  }
}

// A distortion polynomial that folds back: rays past the fold are refused both ways.
TEST(CameraTest, EquisolidFoldIsOutsideTheValidFieldOfView) {
  CameraInfo info = EquisolidInfo();
  info.distortion = {-0.3, 0.0, 0.0, 0.0};
  const Camera camera(info);
  const double theta_max = std::atan(camera.max_normalized_radius());
  EXPECT_LT(theta_max, 1.2);
  const auto rho = [](double theta) { return 2.0 * std::sin(0.5 * theta) * (1.0 - 0.3 * theta * theta); };
  EXPECT_GT(rho(theta_max), rho(theta_max * 0.99));
  EXPECT_GT(rho(theta_max), rho(theta_max * 1.01));
  EXPECT_FALSE(camera.Project(Eigen::Vector3d(std::tan(theta_max * 1.01), 0.0, 1.0)).has_value());
  EXPECT_TRUE(camera.Project(Eigen::Vector3d(std::tan(theta_max * 0.99), 0.0, 1.0)).has_value());
  const double f = info.intrinsics[0];
  EXPECT_FALSE(camera.Unproject(Eigen::Vector2d(640.0 + 1.01 * f * rho(theta_max), 512.0)).has_value());
}

TEST(CameraTest, RadtanAgreesWithOpenCv) {
  const Camera camera(RadtanInfo());
  const std::vector<Eigen::Vector3d> points = RandomPoints(2000, 0.75, 7);
  std::vector<cv::Point3d> cv_points;
  for (const auto& p : points) cv_points.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> cv_px;
  cv::projectPoints(cv_points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CvK(camera.info()),
                    camera.info().distortion, cv_px);
  for (size_t i = 0; i < points.size(); ++i) {
    const std::optional<Eigen::Vector2d> px = camera.Project(points[i]);
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR(px->x(), cv_px[i].x, 1e-6);
    EXPECT_NEAR(px->y(), cv_px[i].y, 1e-6);
  }
}

TEST(CameraTest, FisheyeAgreesWithOpenCv) {
  const Camera camera(FisheyeInfo());
  // Normalized radius up to tan(80 deg).
  const std::vector<Eigen::Vector3d> points = RandomPoints(2000, std::tan(80.0 * M_PI / 180.0), 8);
  std::vector<cv::Point3d> cv_points;
  for (const auto& p : points) cv_points.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> cv_px;
  cv::fisheye::projectPoints(cv_points, cv_px, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CvK(camera.info()),
                             camera.info().distortion);
  for (size_t i = 0; i < points.size(); ++i) {
    const std::optional<Eigen::Vector2d> px = camera.Project(points[i]);
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR(px->x(), cv_px[i].x, 1e-6);
    EXPECT_NEAR(px->y(), cv_px[i].y, 1e-6);
  }
}

void ExpectJacobianMatchesCentralDifferences(const Camera& camera,
                                             const std::vector<Eigen::Vector3d>& points) {
  for (const Eigen::Vector3d& p : points) {
    Eigen::Matrix<double, 2, 3> J;
    ASSERT_TRUE(camera.Project(p, &J).has_value());
    Eigen::Matrix<double, 2, 3> J_numeric;
    const double h = 1e-6 * p.z();
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d dp = h * Eigen::Vector3d::Unit(c);
      J_numeric.col(c) = (*camera.Project(p + dp) - *camera.Project(p - dp)) / (2.0 * h);
    }
    EXPECT_LE((J - J_numeric).norm(), 1e-5 * std::max(1.0, J.norm())) << "at " << p.transpose() << "\n"
                                                                      << J << "\n"
                                                                      << J_numeric;
  }
}

TEST(CameraTest, AnalyticJacobianMatchesCentralDifferences) {
  ExpectJacobianMatchesCentralDifferences(Camera(RadtanInfo()), RandomPoints(300, 0.75, 9));
  ExpectJacobianMatchesCentralDifferences(Camera(FisheyeInfo()), RandomPoints(300, 5.0, 10));
  ExpectJacobianMatchesCentralDifferences(Camera(EquisolidInfo()), RandomPoints(300, 5.0, 13));
  ExpectJacobianMatchesCentralDifferences(Camera(DistortedEquisolidInfo()), RandomPoints(300, 5.0, 14));
}

void ExpectJetMatchesAnalytic(const Camera& camera, const std::vector<Eigen::Vector3d>& points) {
  using Jet = ceres::Jet<double, 3>;
  for (const Eigen::Vector3d& p : points) {
    Eigen::Matrix<double, 2, 3> J;
    const std::optional<Eigen::Vector2d> px = camera.Project(p, &J);
    ASSERT_TRUE(px.has_value());
    const Jet p_jet[3] = {Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2)};
    Jet px_jet[2];
    ASSERT_TRUE(camera.Project(p_jet, px_jet));
    for (int r = 0; r < 2; ++r) {
      EXPECT_NEAR(px_jet[r].a, (*px)(r), 1e-9);
      ASSERT_TRUE(px_jet[r].v.allFinite()) << "at " << p.transpose();
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(px_jet[r].v(c), J(r, c), 1e-9 * std::max(1.0, J.norm())) << "at " << p.transpose();
      }
    }
  }
}

TEST(CameraTest, JetDerivativesMatchAnalyticJacobian) {
  ExpectJetMatchesAnalytic(Camera(RadtanInfo()), RandomPoints(300, 0.75, 11));
  ExpectJetMatchesAnalytic(Camera(FisheyeInfo()), RandomPoints(300, 5.0, 12));
  ExpectJetMatchesAnalytic(Camera(EquisolidInfo()), RandomPoints(300, 5.0, 15));
  ExpectJetMatchesAnalytic(Camera(DistortedEquisolidInfo()), RandomPoints(300, 5.0, 16));
}

// The r -> 0 series of the equidistant scale s(u) = theta_d / r against the closed form in
// long double, on both sides of the switch, and its slope against the closed form's.
TEST(CameraTest, EquidistantSeriesMatchesClosedForm) {
  const std::vector<double> d = FisheyeInfo().distortion;
  const auto closed_form = [&d](long double u) {
    const long double r = std::sqrt(u), theta = std::atan(r), t2 = theta * theta;
    return theta * (1.0L + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])))) / r;
  };
  for (double u : {1e-14, 1e-11, 1e-9, 0.999e-8, 1.001e-8, 1e-7}) {
    EXPECT_NEAR(EquidistantScale(d.data(), u), static_cast<double>(closed_form(u)), 1e-15) << u;
    const long double h = 1e-3L * u;
    const double slope = static_cast<double>((closed_form(u + h) - closed_form(u - h)) / (2.0L * h));
    using Jet = ceres::Jet<double, 1>;
    const Jet d_jet[4] = {Jet(d[0]), Jet(d[1]), Jet(d[2]), Jet(d[3])};
    const Jet s = EquidistantScale(d_jet, Jet(u, 0));
    if (u >= 1e-9) {  // below, long double differences are noise
      EXPECT_NEAR(s.v(0), slope, 1e-6) << u;
    }
    EXPECT_NEAR(s.v(0), d[0] - 1.0 / 3.0, 1e-6) << u;  // s'(0) = k1 - 1/3
  }
}

TEST(CameraTest, FisheyeOnAxisJacobianIsFocalOverDepth) {
  const Camera camera(FisheyeInfo());
  Eigen::Matrix<double, 2, 3> J;
  const std::optional<Eigen::Vector2d> px = camera.Project(Eigen::Vector3d(0.0, 0.0, 2.0), &J);
  ASSERT_TRUE(px.has_value());
  EXPECT_DOUBLE_EQ(px->x(), 421.079);
  EXPECT_DOUBLE_EQ(px->y(), 400.527);
  Eigen::Matrix<double, 2, 3> expected;
  expected << 283.943 / 2.0, 0.0, 0.0, 0.0, 284.986 / 2.0, 0.0;
  EXPECT_LE((J - expected).norm(), 1e-12);
}

TEST(CameraTest, BehindOrOnTheCameraPlaneIsRejected) {
  for (const CameraInfo& info : {RadtanInfo(), FisheyeInfo(), EquisolidInfo()}) {
    const Camera camera(info);
    const std::vector<Eigen::Vector3d> points = {
        Eigen::Vector3d(0.1, 0.2, -1.0), Eigen::Vector3d(0.0, 0.0, -1.0), Eigen::Vector3d(0.1, 0.0, 0.0),
        Eigen::Vector3d(0.0, 0.0, 1e-9), Eigen::Vector3d(0.0, 0.0, std::nan(""))};
    for (const Eigen::Vector3d& p : points) {
      EXPECT_FALSE(camera.Project(p).has_value()) << p.transpose();
      double px[2] = {-7.0, -7.0};
      EXPECT_FALSE(camera.Project(p.data(), px)) << p.transpose();
      EXPECT_EQ(px[0], -7.0);  // untouched
    }
  }
}

TEST(CameraTest, RadtanFoldIsOutsideTheValidFieldOfView) {
  const Camera camera(RadtanInfo());
  const double r_max = camera.max_normalized_radius();
  const auto& d = camera.info().distortion;
  const auto slope = [&d](double r) {
    const double u = r * r;
    return 1.0 + 3.0 * d[0] * u + 5.0 * d[1] * u * u + 7.0 * d[4] * u * u * u;
  };
  EXPECT_GT(slope(r_max * 0.999), 0.0);
  EXPECT_LT(slope(r_max * 1.001), 0.0);
  // Far past the fold OpenCV's polynomial maps a point 60 degrees off-axis back near the
  // image centre; ProjectPoint reproduces OpenCV, Camera::Project refuses it.
  const Eigen::Vector3d p(std::tan(60.0 * M_PI / 180.0), 0.0, 1.0);
  double px[2];
  EXPECT_TRUE(camera.Project(p.data(), px));
  EXPECT_TRUE(camera.info().InImage(Eigen::Vector2d(px[0], px[1])));
  EXPECT_FALSE(camera.Project(p).has_value());
  EXPECT_FALSE(camera.Unproject(Eigen::Vector2d(1e5, 1e5)).has_value());
}

// Beyond the image, up to the fold: every ray inside the valid field of view comes back
// from its pixel, and pixels past the fold's radius have no ray.
TEST(CameraTest, RadtanUnprojectsUpToTheFold) {
  const Camera camera(RadtanInfo());
  const double r_max = camera.max_normalized_radius();
  const auto& k = camera.info().intrinsics;
  double worst = 0.0;
  for (double angle = 0.0; angle < 2.0 * M_PI; angle += 0.05) {
    const Eigen::Vector2d direction(std::cos(angle), std::sin(angle));
    for (double f = 0.0; f <= 0.999; f += 0.003) {
      const Eigen::Vector3d ray_true(f * r_max * direction.x(), f * r_max * direction.y(), 1.0);
      const std::optional<Eigen::Vector2d> px = camera.Project(ray_true);
      ASSERT_TRUE(px.has_value());
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(*px);
      ASSERT_TRUE(ray.has_value()) << "fraction of r_max " << f << " angle " << angle;
      worst = std::max(worst, (*ray - ray_true).norm());
    }
    // The distorted radius at the fold, then 2 % further out.
    const Eigen::Vector2d px_fold =
        *camera.Project(Eigen::Vector3d(r_max * direction.x(), r_max * direction.y(), 1.0));
    const Eigen::Vector2d xy_d_fold((px_fold.x() - k[2]) / k[0], (px_fold.y() - k[3]) / k[1]);
    const Eigen::Vector2d xy_d_out = 1.02 * xy_d_fold;
    EXPECT_FALSE(camera.Unproject(Eigen::Vector2d(k[0] * xy_d_out.x() + k[2], k[1] * xy_d_out.y() + k[3])))
        << "angle " << angle;
  }
  EXPECT_LE(worst, 1e-10);
}

TEST(CameraTest, UndistortedCameraHasUnboundedFieldOfView) {
  CameraInfo info = RadtanInfo();
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  const Camera camera(info);
  EXPECT_TRUE(std::isinf(camera.max_normalized_radius()));
  const std::optional<Eigen::Vector3d> ray =
      camera.Unproject(Eigen::Vector2d(1506.9 * 3.0 + 641.176, 524.495));
  ASSERT_TRUE(ray.has_value());
  EXPECT_NEAR(ray->x(), 3.0, 1e-12);
  EXPECT_NEAR(ray->y(), 0.0, 1e-12);
}

TEST(CameraTest, BadCalibrationThrows) {
  CameraInfo info = RadtanInfo();
  info.distortion.pop_back();
  EXPECT_THROW(Camera{info}, std::runtime_error);
  info = FisheyeInfo();
  info.distortion.push_back(0.0);
  EXPECT_THROW(Camera{info}, std::runtime_error);
  info = EquisolidInfo();
  info.distortion.pop_back();
  EXPECT_THROW(Camera{info}, std::runtime_error);
  info = RadtanInfo();
  info.intrinsics[0] = 0.0;
  EXPECT_THROW(Camera{info}, std::runtime_error);
  info = RadtanInfo();
  info.distortion[1] = std::nan("");
  EXPECT_THROW(Camera{info}, std::runtime_error);
  info = RadtanInfo();
  info.width = 0;
  EXPECT_THROW(Camera{info}, std::runtime_error);
  EXPECT_FALSE(Camera(RadtanInfo()).Unproject(Eigen::Vector2d(std::nan(""), 1.0)).has_value());
}

}  // namespace
}  // namespace waymark
