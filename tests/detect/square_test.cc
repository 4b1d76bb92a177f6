// The square ceiling marker's detector (detect/square.h) on LED pairs rendered by the
// square-ceiling scenario's infrared renderer (sim/ir_render.h): corners against the exact ones,
// the solid side found where it is, occlusion of half of each side survived, the solid side
// hidden refused (no flip), and bad pairs refused with one line.
#include "detect/square.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "geometry/square_marker.h"
#include "sim/ir_render.h"
#include "sim/scenarios.h"

namespace waymark {
namespace {

using ::testing::HasSubstr;

class DetectSquareTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::ParamSet params = sim::ScenarioParams("square-ceiling");
    params.SetAssignment("ir.people=0");
    scene_ = new sim::Scene(sim::BuildScene("square-ceiling", params));
    renderer_ = new sim::IrRenderer(scene_->world, *scene_->ir_room, sim::IrOptionsFromParams(params), 7);
    camera_ = new Camera(scene_->world.cameras[0]);
  }
  static void TearDownTestSuite() {
    delete renderer_;
    delete scene_;
    delete camera_;
  }

  // The camera 0.3 m above (x, y), heading yaw (image up = robot forward).
  static SE3d CameraAt(double x, double y, double yaw) {
    const SE3d T_world_robot(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
                             Eigen::Vector3d(x, y, 0.0));
    return T_world_robot * scene_->world.cameras[0].T_robot_camera;
  }
  static std::array<Eigen::Vector2d, 4> TrueCorners(const SE3d& T_world_camera) {
    const sim::SimMarker& square = scene_->world.markers[0];
    std::array<Eigen::Vector2d, 4> px;
    const std::array<Eigen::Vector3d, 4> object = MarkerCorners(square.size_m);
    for (int k = 0; k < 4; ++k)
      px[k] = *camera_->Project(T_world_camera.inverse() * (square.T_world_marker * object[k]));
    return px;  // solid side top: its own order is solid first
  }
  // Hides the ceiling rectangle [x0, x1] x [y0, y1] (world) in the on image: the tape there
  // is as dark as with the LEDs off.
  static void Hide(const SE3d& T_world_camera, double x0, double x1, double y0, double y1, const cv::Mat& off,
                   cv::Mat* on) {
    std::vector<cv::Point> polygon;
    const double z = scene_->world.markers[0].T_world_marker.translation().z();
    const std::array<Eigen::Vector2d, 5> loop = {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                                 Eigen::Vector2d(x1, y1), Eigen::Vector2d(x0, y1),
                                                 Eigen::Vector2d(x0, y0)};
    for (int e = 0; e < 4; ++e) {
      for (int k = 0; k < 50; ++k) {
        const Eigen::Vector2d p = loop[e] + (loop[e + 1] - loop[e]) * (k / 50.0);
        const Eigen::Vector2d px =
            *camera_->Project(T_world_camera.inverse() * Eigen::Vector3d(p.x(), p.y(), z));
        polygon.emplace_back(cvRound(px.x()), cvRound(px.y()));
      }
    }
    cv::Mat mask(on->size(), CV_8U, cv::Scalar(0));
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(255));
    off.copyTo(*on, mask);
  }
  static SquareDetector Detector() {
    SquareDetectorOptions options;
    options.ceiling_height_m = 2.0;
    return SquareDetector(*camera_, options);
  }

  static sim::Scene* scene_;
  static sim::IrRenderer* renderer_;
  static Camera* camera_;
};

sim::Scene* DetectSquareTest::scene_ = nullptr;
sim::IrRenderer* DetectSquareTest::renderer_ = nullptr;
Camera* DetectSquareTest::camera_ = nullptr;

TEST_F(DetectSquareTest, CornersWithinAFractionOfAPixel) {
  const SquareDetector detector = Detector();
  struct Place {
    double x, y, yaw;
  };
  int index = 0;
  for (const Place& place :
       {Place{0.0, 0.0, 0.0}, Place{0.8, -0.5, 1.0}, Place{-1.2, 1.1, 2.5}, Place{1.5, 1.4, -2.0}}) {
    const SE3d T_world_camera = CameraAt(place.x, place.y, place.yaw);
    const cv::Mat on = renderer_->Render(*camera_, T_world_camera, 0.0, true, 10 * index);
    const cv::Mat off = renderer_->Render(*camera_, T_world_camera, 0.0, false, 10 * index + 1);
    const std::vector<SquareDetection> found = detector.Detect(on, off);
    ASSERT_EQ(found.size(), 1u) << "place " << index;
    const std::array<Eigen::Vector2d, 4> truth = TrueCorners(T_world_camera);
    for (int k = 0; k < 4; ++k) {
      EXPECT_LE((found[0].corners_px[k] - truth[k]).norm(), 0.3) << "place " << index << " corner " << k;
      // Profiles every 2 cm over the 1.85 m between the ends: all on the solid side, about half
      // on a dashed one (its gaps give none).
      EXPECT_GT(found[0].refined_samples[k], k == 0 ? 60 : 25) << "place " << index << " side " << k;
    }
    EXPECT_GT(found[0].longest_run_m[0], 1.5);  // the solid side
    for (int k = 1; k < 4; ++k) EXPECT_LT(found[0].longest_run_m[k], 0.2);
    ++index;
  }
}

TEST_F(DetectSquareTest, HalfOfEverySideHiddenIsSurvived) {
  const SquareDetector detector = Detector();
  const SE3d T_world_camera = CameraAt(0.3, 0.2, 0.7);
  cv::Mat on = renderer_->Render(*camera_, T_world_camera, 0.0, true, 100);
  const cv::Mat off = renderer_->Render(*camera_, T_world_camera, 0.0, false, 101);
  // The solid side is world y = -1 (marker +y); the others y = +1, x = -1, x = +1.
  Hide(T_world_camera, -1.1, -0.05, -1.1, -0.9, off, &on);  // solid: its left half
  Hide(T_world_camera, 0.05, 1.1, 0.9, 1.1, off, &on);      // opposite: its right half
  Hide(T_world_camera, -1.1, -0.9, 0.05, 1.1, off, &on);    // left side: one half
  Hide(T_world_camera, 0.9, 1.1, -1.1, -0.05, off, &on);    // right side: the other half
  const std::vector<SquareDetection> found = detector.Detect(on, off);
  ASSERT_EQ(found.size(), 1u);
  const std::array<Eigen::Vector2d, 4> truth = TrueCorners(T_world_camera);
  for (int k = 0; k < 4; ++k) {
    EXPECT_LE((found[0].corners_px[k] - truth[k]).norm(), 0.5)
        << "corner " << k << " samples " << found[0].refined_samples[k] << " run "
        << found[0].longest_run_m[k];
  }
}

TEST_F(DetectSquareTest, SolidSideHiddenGivesNoFixRatherThanAFlip) {
  const SquareDetector detector = Detector();
  const SE3d T_world_camera = CameraAt(-0.4, 0.3, -0.5);
  cv::Mat on = renderer_->Render(*camera_, T_world_camera, 0.0, true, 200);
  const cv::Mat off = renderer_->Render(*camera_, T_world_camera, 0.0, false, 201);
  ASSERT_EQ(detector.Detect(on, off).size(), 1u);
  Hide(T_world_camera, -1.2, 1.2, -1.1, -0.9, off, &on);  // the whole solid side
  EXPECT_TRUE(detector.Detect(on, off).empty());
}

TEST_F(DetectSquareTest, NoSquareNoDetection) {
  const SquareDetector detector = Detector();
  const SE3d T_world_camera = CameraAt(0.0, 0.0, 0.0);
  const cv::Mat off = renderer_->Render(*camera_, T_world_camera, 0.0, false, 300);
  EXPECT_TRUE(detector.Detect(off, off).empty());
}

TEST_F(DetectSquareTest, BadPairsAreRefusedWithOneLine) {
  const SquareDetector detector = Detector();
  const cv::Mat full(1024, 1280, CV_8U, cv::Scalar(0)), half(512, 640, CV_8U, cv::Scalar(0));
  const auto message = [&](const cv::Mat& on, const cv::Mat& off) -> std::string {
    try {
      detector.Detect(on, off);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_EQ(message(full, half), "LED pair: the on image is 1280x1024 but the off image is 640x512");
  EXPECT_EQ(message(half, half), "LED pair: images are 640x512 but camera up is 1280x1024");
  EXPECT_EQ(message(cv::Mat(), full), "LED pair: empty image");
  EXPECT_EQ(message(cv::Mat(1024, 1280, CV_8UC3), cv::Mat(1024, 1280, CV_8UC3)),
            "LED pair: expected 8-bit gray images");
  SquareDetectorOptions options;
  options.ceiling_height_m = -1.0;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_THAT(why, HasSubstr("ceiling height: expected > 0 m"));
  options = SquareDetectorOptions{};
  options.tape.tape_width_m = 1.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_THAT(why, HasSubstr("tape_width_m"));
  EXPECT_THROW(SquareDetector(*camera_, options), std::invalid_argument);
}

TEST_F(DetectSquareTest, CeilingHeightFromTheMap) {
  MarkerMap map;
  MapMarker square;
  square.key = {kFamilySquare, "S0"};
  square.size_m = 2.0;
  square.T_world_marker = scene_->world.markers[0].T_world_marker;
  map.markers.push_back(square);
  EXPECT_NEAR(*SquareCeilingHeight(map, scene_->world.cameras[0]), 2.0, 1e-12);
  map.markers[0].key.family = kFamilyQr;
  EXPECT_FALSE(SquareCeilingHeight(map, scene_->world.cameras[0]).has_value());
}

}  // namespace
}  // namespace waymark
