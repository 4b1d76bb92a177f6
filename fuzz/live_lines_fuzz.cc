// `waymark localize --live` input lines (online/live_input.h) against a small map: arbitrary
// text, one line per input line. Nothing may stop the stream: every line is answered, counted
// as malformed or ignored.
#include <sstream>

#include "fuzz/fuzz_util.h"
#include "geometry/camera.h"
#include "runner/live_input.h"

namespace {

struct World {
  waymark::Dataset dataset;
  waymark::MarkerMap map;
  waymark::LocalizeRunOptions options;
};

World& TheWorld() {
  static World world = [] {
    World w;
    w.dataset.config.name = "fuzz";
    w.dataset.config.cameras = {"cam0"};
    waymark::CameraInfo camera;
    camera.name = "cam0";
    camera.width = 640;
    camera.height = 480;
    camera.intrinsics = {500, 500, 320, 240};
    camera.distortion = std::vector<double>(waymark::CameraInfo::DistortionSize(camera.model), 0.0);
    w.dataset.cameras["cam0"] = camera;
    for (int i = 0; i < 4; ++i) {
      waymark::MapMarker marker;
      marker.key = {"qr", "M" + std::to_string(i)};
      marker.size_m = 0.2;
      marker.T_world_marker = waymark::SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(i, 0, 2));
      marker.fixed = true;
      w.map.markers.push_back(marker);
    }
    w.options.localizer = waymark::DefaultLocalizerOptions(w.dataset);
    return w;
  }();
  return world;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  World& world = TheWorld();
  std::ostringstream out, err;
  try {
    waymark::LiveInput live(world.dataset, world.map, world.options, out, err);
    std::istringstream in(waymark::fuzz::Text(data, size));
    live.Run(in);
  } catch (const std::runtime_error&) {  // CheckMapMatches: codes seen, none of the map's
  }
  return 0;
}
