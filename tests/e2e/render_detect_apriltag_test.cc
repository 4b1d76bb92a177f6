// Render -> detect end to end for AprilTag 36h11 (tests/e2e/render_detect_util.h): no
// scenario has AprilTags, so rooms' and the drone warehouse's codes are redrawn as tags
// (tag number = the code's index).
#include "tests/e2e/render_detect_util.h"

namespace waymark::e2e {
namespace {

TEST(RenderDetectAprilTagTest, RoomsRedrawn) {
  ExpectAccepted("rooms as apriltag", RenderAndDetect("rooms", "apriltag-36h11", 30), 40);
}

TEST(RenderDetectAprilTagTest, WarehouseDroneRedrawn) {
  ExpectAccepted("warehouse-drone as apriltag", RenderAndDetect("warehouse-drone", "apriltag-36h11", 30), 40);
}

}  // namespace
}  // namespace waymark::e2e
