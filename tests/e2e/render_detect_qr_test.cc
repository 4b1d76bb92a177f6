// Render -> detect end to end for QR codes (tests/e2e/render_detect_util.h): the three QR
// scenarios as they are. Split from the DataMatrix and AprilTag files so ctest -j runs them
// side by side.
//
// Measured 2026-11-23 (QR detector with the finder-pattern pass and the dark-module side
// fit, detect/qr_finder.h and detect/qr_grid.h):
//   corridor         70 images  70/70 wide codes matched, worst corner 0.497 px (C052,
//                    91 px, whose quiet zone clips at 255)
//   warehouse-drone  40 images 100/100 matched (was 95/100, 97 read), worst 0.281 px (was 0.70)
//   ceiling-grid     10 images  10/10 matched (was 1/10), worst 0.358 px
// The ceiling codes are barely over 40 px (12 cm at 1.85 m, f = 620 px: 1.9 px per module
// under a 0.7 px blur): zxing-cpp does not read them in the frame; the finder pass reads
// them resampled upright. The drone's floor and rack codes are seen obliquely at 640x480.
#include "tests/e2e/render_detect_util.h"

namespace waymark::e2e {
namespace {

TEST(RenderDetectQrTest, Corridor) { ExpectAccepted("corridor", RenderAndDetect("corridor", "", 70), 60); }

TEST(RenderDetectQrTest, WarehouseDrone) {
  ExpectAccepted("warehouse-drone", RenderAndDetect("warehouse-drone", "", 40), 60);
}

TEST(RenderDetectQrTest, CeilingGrid) {
  ExpectAccepted("ceiling-grid", RenderAndDetect("ceiling-grid", "", 10), 5);
}

}  // namespace
}  // namespace waymark::e2e
