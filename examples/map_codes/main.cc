// Loads a Waymark map and prints each code: family, id, size and position in the world frame.
// Built against the installed package (examples/map_codes/CMakeLists.txt); usage: map_codes MAP.json
#include <waymark/io/map_io.h>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
  if (argc != 2) return std::fprintf(stderr, "usage: map_codes MAP.json\n"), 2;
  try {
    for (const waymark::MapMarker& m : waymark::ReadMap(argv[1]).markers) {
      const Eigen::Vector3d p = m.T_world_marker.translation();
      std::printf("%s %s %.3f m at %.3f %.3f %.3f\n", m.key.family.c_str(), m.key.id.c_str(), m.size_m, p.x(),
                  p.y(), p.z());
    }
  } catch (const std::exception& e) {
    return std::fprintf(stderr, "map_codes: %s\n", e.what()), 1;
  }
}
