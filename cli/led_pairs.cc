#include "cli/led_pairs.h"

#include <map>
#include <stdexcept>

#include "geometry/square_marker.h"

namespace waymark::cli {
namespace {

// "images/up/000001-on.png" -> "images/up/000001-off.png"; nullopt if not an -on image.
std::optional<std::string> OffPartner(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || dot < 3 || (slash != std::string::npos && dot < slash)) return std::nullopt;
  if (path.compare(dot - 3, 3, "-on") != 0) return std::nullopt;
  return path.substr(0, dot - 3) + "-off" + path.substr(dot);
}

bool IsOff(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  return dot != std::string::npos && dot >= 4 && (slash == std::string::npos || dot > slash) &&
         path.compare(dot - 4, 4, "-off") == 0;
}

}  // namespace

void SplitLedPairs(const std::vector<ImageEntry>& rows, const std::string& where, std::vector<LedPair>* pairs,
                   std::vector<ImageEntry>* others) {
  std::map<std::string, ImageEntry> pending;  // camera -> its on row waiting for the off row
  const auto lone_on = [&](const ImageEntry& on) {
    throw std::runtime_error(where + ": LED-on image '" + on.path + "' (camera " + on.camera +
                             ") has no LED-off partner '" + *OffPartner(on.path) +
                             "' on the camera's next row");
  };
  for (const ImageEntry& row : rows) {
    const auto it = pending.find(row.camera);
    if (OffPartner(row.path)) {
      if (it != pending.end()) lone_on(it->second);
      pending.emplace(row.camera, row);
    } else if (IsOff(row.path)) {
      if (it == pending.end() || *OffPartner(it->second.path) != row.path) {
        if (it != pending.end()) lone_on(it->second);
        throw std::runtime_error(where + ": LED-off image '" + row.path + "' (camera " + row.camera +
                                 ") has no LED-on partner on the camera's previous row");
      }
      pairs->push_back({it->second, row});
      pending.erase(it);
    } else {
      if (it != pending.end()) lone_on(it->second);
      others->push_back(row);
    }
  }
  if (!pending.empty()) lone_on(pending.begin()->second);
}

SquareDetectorOptions SquareOptionsFor(const Dataset& dataset, const CameraInfo& camera) {
  const std::string where = "dataset " + dataset.dir.string();
  if (!dataset.known_markers) {
    throw std::runtime_error(where + ": family square needs the squares' sizes and heights in markers.json");
  }
  SquareDetectorOptions options;
  const MapMarker* first = nullptr;
  for (const MapMarker& m : dataset.known_markers->markers) {
    if (m.key.family != kFamilySquare || !m.has_pose) continue;
    const SquareTape tape = TapeOf(m);
    if (first == nullptr) {
      first = &m;
      options.side_m = m.size_m;
      options.tape = tape;
    } else if (m.size_m != first->size_m || tape.tape_width_m != options.tape.tape_width_m ||
               tape.dash_m != options.tape.dash_m || tape.gap_m != options.tape.gap_m) {
      throw std::runtime_error(where + ": markers.json: squares " + first->key.id + " and " + m.key.id +
                               " differ in size or tape; square detection needs them alike");
    }
  }
  const std::optional<double> height = SquareCeilingHeight(*dataset.known_markers, camera);
  if (first == nullptr || !height) {
    throw std::runtime_error(where + ": family square needs a square with a pose above camera " +
                             camera.name + " in markers.json");
  }
  options.ceiling_height_m = *height;
  return options;
}

const MapMarker* OnlySquare(const Dataset& dataset) {
  if (!dataset.known_markers) return nullptr;
  const MapMarker* only = nullptr;
  for (const MapMarker& m : dataset.known_markers->markers) {
    if (m.key.family != kFamilySquare || !m.has_pose) continue;
    if (only != nullptr) return nullptr;
    only = &m;
  }
  return only;
}

}  // namespace waymark::cli
