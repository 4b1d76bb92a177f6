// Render -> detect end to end for QR codes (tests/e2e/render_detect_util.h): the three QR
// scenarios as they are. Split from the DataMatrix and AprilTag files so ctest -j runs them
// side by side.
#include "tests/e2e/render_detect_util.h"

namespace waymark::e2e {
namespace {

TEST(RenderDetectQrTest, Corridor) { ExpectAccepted("corridor", RenderAndDetect("corridor", "", 70), 60); }

// Known failure (2026-11-23, QR detector of the working tree): 95/100 wide codes matched,
// 97 detected, worst corner error 0.70 px (floor and rack codes seen obliquely, 640x480).
// Enable once core/detect_qr* reaches the acceptance.
TEST(RenderDetectQrTest, DISABLED_WarehouseDrone) {
  ExpectAccepted("warehouse-drone", RenderAndDetect("warehouse-drone", "", 40), 60);
}

// Known failure (2026-11-23): 1/10 wide codes read. The ceiling codes are barely over
// 40 px (12 cm at 1.85 m, f = 620 px; QR version 2 with the "i/x/y" payload: 1.6-1.8 px
// per module under a 0.7 px blur), which the QR detector does not read yet.
TEST(RenderDetectQrTest, DISABLED_CeilingGrid) {
  ExpectAccepted("ceiling-grid", RenderAndDetect("ceiling-grid", "", 10), 5);
}

}  // namespace
}  // namespace waymark::e2e
