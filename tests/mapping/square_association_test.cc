// ID-less squares of a survey told apart by the odometry (mapping/square_association.h): three
// alike squares 6 m apart, a drive along them and back with drifting odometry, every detection
// "*" (or the name of markers.json's only square): each gets its true square, and the map build's
// ingest makes three markers of them. Errors: no odometry, no size.
#include "mapping/square_association.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "geometry/camera.h"
#include "geometry/square_marker.h"
#include "mapping/survey.h"
#include "tests/test_cameras.h"

namespace waymark {
namespace {

using ::testing::HasSubstr;

SE3d SquarePose(int i) {
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // facing down
  return SE3d(Eigen::Quaterniond(R), Eigen::Vector3d(6.0 * i, 0.0, 2.3));
}

// Robot truth at time t: along x from -1 to 13 m in 70 s, then back.
SE3d Truth(double t) {
  const double x = t <= 70.0 ? -1.0 + 0.2 * t : 13.0 - 0.2 * (t - 70.0);
  return SE2d(x, 0.3 * std::sin(0.1 * t), t <= 70.0 ? 0.0 : M_PI).ToSE3();
}

// The survey: detections of every square fully in view, id `id` (solid side first: the default
// tape's solid side is the top, so that is the marker's own order); the odometry 3 % long and
// turning 0.3 deg per metre.
Dataset Survey3(const std::string& id) {
  Dataset dataset;
  dataset.dir = "survey";
  CameraInfo info = testing::Seed002EquisolidInfo();
  info.name = "up";
  info.T_robot_camera = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.3));
  dataset.cameras["up"] = info;
  dataset.config.cameras = {"up"};
  const Camera camera(info);
  SE3d odom;
  SE3d previous = Truth(0.0);
  for (int k = 0; k <= 1400; ++k) {
    const double t = 0.1 * k;
    const SE3d truth = Truth(t);
    const SE2d step = SE2d::FromSE3(previous.inverse() * truth);
    odom =
        odom * SE2d(1.03 * step.x(), 1.03 * step.y(), step.theta() + 0.0052 * std::hypot(step.x(), step.y()))
                   .ToSE3();
    previous = truth;
    dataset.odometry.push_back({t, odom});
    DetectionFrame frame;
    frame.stamp_s = t;
    frame.camera = "up";
    const SE3d T_camera_world = (truth * info.T_robot_camera).inverse();
    for (int i = 0; i < 3; ++i) {
      MarkerObservation m;
      m.key = {kFamilySquare, id};
      bool seen = true;
      const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(2.0);
      for (int c = 0; c < 4 && seen; ++c) {
        const auto px = camera.Project(T_camera_world * (SquarePose(i) * corners[c]));
        seen = px && info.InImage(*px) &&
               (SquarePose(i).translation() - truth.translation()).head<2>().norm() < 4.0;
        if (seen) m.corners_px[c] = *px;
      }
      if (seen) frame.markers.push_back(m);
    }
    dataset.detections.push_back(frame);
  }
  MarkerMap known;
  MapMarker s0;
  s0.key = {kFamilySquare, "S0"};
  s0.size_m = 2.0;
  s0.T_world_marker = SquarePose(0);
  s0.fixed = true;
  known.markers.push_back(s0);
  dataset.known_markers = known;
  return dataset;
}

// Index of the true square of a detection (the nearest centre to its corners' mean ray).
void ExpectTrueSquares(const Dataset& input, const Dataset& out) {
  const char* names[3] = {"S0", "S1", "S2"};  // new squares are named in the order first seen
  int checked = 0;
  for (size_t f = 0; f < input.detections.size(); ++f) {
    const SE3d truth = Truth(input.detections[f].stamp_s);
    ASSERT_EQ(out.detections[f].markers.size(), input.detections[f].markers.size());
    for (const MarkerObservation& m : out.detections[f].markers) {
      int nearest = 0;
      const Camera camera(input.cameras.at("up"));
      double best = 1e9;
      for (int i = 0; i < 3; ++i) {
        const auto px = camera.Project((truth * input.cameras.at("up").T_robot_camera).inverse() *
                                       (SquarePose(i) * MarkerCorners(2.0)[0]));
        if (px && (*px - m.corners_px[0]).norm() < best) {
          best = (*px - m.corners_px[0]).norm();
          nearest = i;
        }
      }
      EXPECT_EQ(m.key.id, names[nearest]) << "t = " << input.detections[f].stamp_s;
      ++checked;
    }
  }
  EXPECT_GT(checked, 500);
}

TEST(SquareAssociationTest, UnnamedSquaresGetTheirTrueSquare) {
  const Dataset input = Survey3(kUnidentifiedSquareId);
  SquareAssociationStats stats;
  const Dataset out = AssociateSquares(input, &stats);
  ExpectTrueSquares(input, out);
  EXPECT_EQ(stats.known_used, 1);
  EXPECT_EQ(stats.new_squares, 2);
  EXPECT_EQ(stats.unplaced, 0);
  // The map build's ingest: three squares, the new ones with their size and tape.
  const Survey survey = IngestDataset(input);
  ASSERT_EQ(survey.markers.size(), 3u);
  for (const SurveyMarker& m : survey.markers) {
    EXPECT_EQ(m.key.family, kFamilySquare);
    EXPECT_EQ(m.size_m, 2.0);
    if (m.key.id != "S0") {
      EXPECT_TRUE(m.square_tape.has_value()) << m.key.ToString();  // new: the tape
    }
  }
}

TEST(SquareAssociationTest, TheOnlyKnownSquaresNameIsReassociated) {
  // `waymark detect` names markers.json's only square in every detection, whichever it saw.
  const Dataset input = Survey3("S0");
  const Dataset out = AssociateSquares(input);
  ExpectTrueSquares(input, out);
}

TEST(SquareAssociationTest, NoOdometryOrNoSizeIsAnError) {
  Dataset input = Survey3(kUnidentifiedSquareId);
  input.odometry.clear();
  EXPECT_THAT([&] { AssociateSquares(input); },
              ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("tells them apart by the odometry")));
  input = Survey3(kUnidentifiedSquareId);
  input.known_markers.reset();
  EXPECT_THAT([&] { AssociateSquares(input); },
              ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("need the squares' side")));
}

}  // namespace
}  // namespace waymark
