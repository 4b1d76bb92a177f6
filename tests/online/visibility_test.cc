#include "online/visibility.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/online/synthetic_corridor.h"

namespace waymark {
namespace {

using testing::CorridorConfig;
using testing::CorridorMap;
using testing::SideCamera;

// A planar state at (x, y, yaw) with diagonal standard deviations.
EkfState PlanarState(double x_m, double y_m, double yaw_rad, double sigma_m, double sigma_rad) {
  EkfState state(MotionModel::kPlanar);
  EXPECT_EQ(
      state.Reset(Eigen::Vector3d(x_m, y_m, yaw_rad),
                  Eigen::Vector3d(sigma_m * sigma_m, sigma_m * sigma_m, sigma_rad * sigma_rad).asDiagonal()),
      StepStatus::kOk);
  return state;
}

const ExpectedCode* FindExpected(const std::vector<ExpectedCode>& expected, const std::string& id) {
  for (const ExpectedCode& code : expected) {
    if (code.marker->key.id == id) return &code;
  }
  return nullptr;
}

// Left-wall codes at x = 0.5, 1.5, ... (ids code-0, code-2, ...), right-wall ones at x = 1.0, 2.0, ...
TEST(VisibilityTest, CodeSquarelyInViewIsExpectedAndOthersAreNot) {
  const CorridorConfig config;
  const MarkerMap map = CorridorMap(config);
  const Camera left(SideCamera("left", true, config.camera_height_m));
  const VisibilityOptions options;
  const std::vector<ExpectedCode> expected =
      PredictExpectedCodes(PlanarState(1.5, 0.0, 0.0, 0.01, 0.005), left, map, CodeIndex(map), options);
  ASSERT_EQ(expected.size(), 1u);  // the right wall's codes face away; the left neighbours are out of view
  EXPECT_EQ(expected[0].marker->key.id, "code-2");
  EXPECT_GT(expected[0].in_view, 0.99);
  EXPECT_NEAR(expected[0].size_px, 500.0 * 0.1 / 0.4, 2.0);  // f s / depth
  EXPECT_NEAR(expected[0].cos_angle, 1.0, 1e-6);
  // Turned around: the left camera faces the right wall, whose codes face it.
  const std::vector<ExpectedCode> turned =
      PredictExpectedCodes(PlanarState(2.0, 0.0, M_PI, 0.01, 0.005), left, map, CodeIndex(map), options);
  ASSERT_EQ(turned.size(), 1u);
  EXPECT_EQ(turned[0].marker->key.id, "code-3");
  // Too small to read: nothing expected.
  VisibilityOptions large;
  large.min_code_px = 200.0;
  EXPECT_TRUE(PredictExpectedCodes(PlanarState(1.5, 0.0, 0.0, 0.01, 0.005), left, map, CodeIndex(map), large)
                  .empty());
}

// The same code near the image edge: a wide heading uncertainty makes it weak evidence.
TEST(VisibilityTest, UncertainPoseLowersTheInViewProbabilityAtTheEdge) {
  const CorridorConfig config;
  const MarkerMap map = CorridorMap(config);
  const Camera left(SideCamera("left", true, config.camera_height_m));
  const VisibilityOptions options;
  // The code 0.2 m ahead of the camera's axis: its far edge about 40 px inside the image.
  const ExpectedCode* sure = nullptr;
  const std::vector<ExpectedCode> tight =
      PredictExpectedCodes(PlanarState(1.3, 0.0, 0.0, 0.005, 0.002), left, map, CodeIndex(map), options);
  sure = FindExpected(tight, "code-2");
  ASSERT_NE(sure, nullptr);
  const std::vector<ExpectedCode> wide =
      PredictExpectedCodes(PlanarState(1.3, 0.0, 0.0, 0.05, 0.1), left, map, CodeIndex(map), options);
  const ExpectedCode* unsure = FindExpected(wide, "code-2");
  ASSERT_NE(unsure, nullptr);
  EXPECT_GT(sure->in_view, 0.95);
  EXPECT_LT(unsure->in_view, 0.7);
  // Centred, the wide covariance still leaves it likely in view.
  const std::vector<ExpectedCode> wide_centred =
      PredictExpectedCodes(PlanarState(1.5, 0.0, 0.0, 0.05, 0.1), left, map, CodeIndex(map), options);
  const ExpectedCode* centred = FindExpected(wide_centred, "code-2");
  ASSERT_NE(centred, nullptr);
  EXPECT_GT(centred->in_view, unsure->in_view + 0.2);
}

// The kept neighbourhood (rescanned every NearCodes::kRescanM) gives the same expected codes as
// the scan of the whole map, all along the corridor and both ways.
TEST(VisibilityTest, NearCodesGiveTheSameExpectedCodesAsTheWholeMap) {
  CorridorConfig config;
  config.length_m = 30.0;
  const MarkerMap map = CorridorMap(config);
  const CodeIndex index(map);
  const Camera left(SideCamera("left", true, config.camera_height_m));
  const VisibilityOptions options;
  NearCodes near_codes;
  size_t expected_total = 0, smallest_near = map.markers.size();
  for (int k = 0; k <= 400; ++k) {
    const double x_m = k <= 200 ? 0.1 * k : 0.1 * (400 - k);
    const EkfState state = PlanarState(x_m, 0.05, k <= 200 ? 0.0 : M_PI, 0.02, 0.01);
    const Eigen::Vector3d camera_world = (state.T_world_robot() * left.info().T_robot_camera).translation();
    const std::vector<size_t>& near = near_codes.Around(index, left, camera_world, options);
    smallest_near = std::min(smallest_near, near.size());
    const std::vector<ExpectedCode> all = PredictExpectedCodes(state, left, map, index, options);
    const std::vector<ExpectedCode> kept =
        PredictExpectedCodes(state, left, map, index, options, std::nullopt, &near);
    ASSERT_EQ(all.size(), kept.size()) << "x " << x_m;
    for (size_t i = 0; i < all.size(); ++i) EXPECT_EQ(all[i].marker, kept[i].marker);
    expected_total += all.size();
  }
  EXPECT_GT(expected_total, 100u);
  EXPECT_LT(smallest_near, map.markers.size() / 2);  // the neighbourhood is a part of the map
}

TEST(VisibilityTest, DetectionOnThePredictedQuadCoversIt) {
  ExpectedCode code;
  code.px << 100, 100, 150, 100, 150, 150, 100, 150;
  const auto quad = [](double u, double v) {
    return std::array<Eigen::Vector2d, 4>{Eigen::Vector2d(u - 10, v - 10), Eigen::Vector2d(u + 10, v - 10),
                                          Eigen::Vector2d(u + 10, v + 10), Eigen::Vector2d(u - 10, v + 10)};
  };
  EXPECT_TRUE(CoversExpected(code, quad(125, 125)));
  EXPECT_TRUE(CoversExpected(code, quad(170, 125)));  // within half the quad's size
  EXPECT_FALSE(CoversExpected(code, quad(300, 125)));
}

// The learned rate follows the run's hit rate, per cell; one code missed where its cell is
// seen gets its own lower rate.
TEST(VisibilityTest, DetectionModelLearnsTheHitRate) {
  VisibilityOptions options;
  options.max_detection_probability = 0.99;
  DetectionModel model(options);
  MapMarker a, b;
  a.key = {kFamilyQr, "a"};
  b.key = {kFamilyQr, "b"};
  ExpectedCode code_a, code_b, far_a;
  code_a.marker = &a;
  code_a.size_px = 100.0;
  code_b = code_a;
  code_b.marker = &b;
  far_a = code_a;
  far_a.size_px = 20.0;
  EXPECT_DOUBLE_EQ(model.Probability("cam", code_a), 0.5);  // the Beta(1, 1) prior
  std::mt19937 rng(11);
  std::bernoulli_distribution hit(0.7);
  for (int i = 0; i < 400; ++i) {
    model.Learn("cam", code_a, hit(rng), 1.0);
    model.Learn("cam", far_a, false, 1.0);  // far away: never read
  }
  EXPECT_NEAR(model.Probability("cam", code_b), 0.7, 0.06);  // the cell's rate for an unseen code
  EXPECT_LT(model.Probability("cam", far_a), 0.02);
  // Misses of `a` where it is far do not lower its rate near by (they were predicted).
  EXPECT_NEAR(model.Probability("cam", code_a), 0.7, 0.08);
  EXPECT_DOUBLE_EQ(model.Probability("other", code_a), 0.5);            // per camera
  for (int i = 0; i < 20; ++i) model.Learn("cam", code_b, false, 1.0);  // b hidden from here
  EXPECT_LT(model.Probability("cam", code_b), 0.3);
}

// Test fixture for the sequential test: `n` expected codes, learned at a 90 % hit rate.
struct TrainedTest {
  MapMarker marker;
  ExpectedCode code;
  NegativeEvidenceTest test{VisibilityOptions()};
  double stamp_s = 0.0;

  TrainedTest() {
    marker.key = {kFamilyQr, "m"};
    code.marker = &marker;
    code.size_px = 100.0;
    code.in_view = 1.0;
    for (const std::string camera : {"left", "right"}) {
      for (int i = 0; i < 200; ++i)
        Frame(camera, i % 10 != 0 ? ExpectedOutcome::kHit : ExpectedOutcome::kMissed, true);
    }
    EXPECT_LT(test.llr(), VisibilityOptions().suspect_llr);
  }
  double Frame(const std::string& camera, ExpectedOutcome outcome, bool learn = false) {
    stamp_s += 0.05;
    return test.AddFrame(stamp_s, camera, {code}, {outcome}, 0, outcome != ExpectedOutcome::kMissed, learn);
  }
};

TEST(VisibilityTest, OneBlindCameraIsSuspectNeverLostAndTwoAreLost) {
  const VisibilityOptions options;
  TrainedTest one;
  double llr = 0.0, max_llr = 0.0;
  for (int i = 0; i < 20; ++i) {  // one camera sees nothing for 2 s while its code is expected
    llr = one.Frame("left", ExpectedOutcome::kMissed);
    max_llr = std::max(max_llr, llr);
  }
  EXPECT_GE(max_llr, options.suspect_llr);
  EXPECT_LT(max_llr, options.lost_llr);
  EXPECT_GT(one.test.blind_probability("left"), 0.9);
  // Seen where predicted again: the camera is not blind, and the track is trusted again.
  EXPECT_LT(one.Frame("left", ExpectedOutcome::kHit), options.suspect_llr);
  EXPECT_DOUBLE_EQ(one.test.blind_probability("left"), 0.0);
  EXPECT_DOUBLE_EQ(one.Frame("left", ExpectedOutcome::kHit), 0.0);
  TrainedTest two;
  for (int i = 0; i < 3; ++i) {
    two.Frame("left", ExpectedOutcome::kMissed);
    llr = two.Frame("right", ExpectedOutcome::kMissed);
  }
  EXPECT_GE(llr, options.lost_llr);
}

TEST(VisibilityTest, FirstMissesOfBothCamerasMakeTheTrackSuspect) {
  TrainedTest test;
  EXPECT_LT(test.Frame("left", ExpectedOutcome::kMissed), VisibilityOptions().suspect_llr);  // a 10 % event
  EXPECT_GE(test.Frame("right", ExpectedOutcome::kMissed), VisibilityOptions().suspect_llr);
  // An occupied code (a misread id on it) is no evidence.
  TrainedTest occupied;
  EXPECT_LT(occupied.Frame("left", ExpectedOutcome::kOccupied), 0.01);
}

TEST(VisibilityTest, EvidenceDecays) {
  TrainedTest test;
  test.Frame("left", ExpectedOutcome::kMissed);
  const double llr = test.Frame("right", ExpectedOutcome::kMissed);
  const double later =
      test.test.AddFrame(test.stamp_s + VisibilityOptions().decay_time_s, "left", {}, {}, 0, false, false);
  EXPECT_NEAR(later, llr * std::exp(-1.0), 1e-9);
}

TEST(VisibilityTest, InvalidOptionsAreRejected) {
  std::string why;
  EXPECT_TRUE(VisibilityOptions().Check(&why)) << why;
  VisibilityOptions bad;
  bad.lost_llr = 1.0;  // below suspect_llr
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_NE(why.find("suspect_llr"), std::string::npos);
  bad = VisibilityOptions();
  bad.blind_stay_probability = 1.0;
  EXPECT_FALSE(bad.Check(&why));
  bad = VisibilityOptions();
  bad.max_angle_deg = 90.0;
  EXPECT_FALSE(bad.Check(&why));
}

}  // namespace
}  // namespace waymark
