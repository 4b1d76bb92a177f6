// Render -> detect end to end for DataMatrix (tests/e2e/render_detect_util.h): rooms as it
// is (8 cm codes, 1280x960), and the corridor's codes redrawn as DataMatrix (640x480, seen
// from the side at up to 60 deg).
#include "tests/e2e/render_detect_util.h"

namespace waymark::e2e {
namespace {

TEST(RenderDetectDataMatrixTest, Rooms) { ExpectAccepted("rooms", RenderAndDetect("rooms", "", 40), 50); }

TEST(RenderDetectDataMatrixTest, CorridorRedrawn) {
  ExpectAccepted("corridor as datamatrix", RenderAndDetect("corridor", "datamatrix", 50), 40);
}

}  // namespace
}  // namespace waymark::e2e
