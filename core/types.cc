#include "core/types.h"

namespace waymark {

bool IsKnownFamily(const std::string& family) {
  if (family == kFamilyQr || family == kFamilyDataMatrix || family == kFamilySquare) return true;
  const std::string prefix = kFamilyAprilTagPrefix;
  return family.size() > prefix.size() && family.compare(0, prefix.size(), prefix) == 0;
}

const MapMarker* MarkerMap::Find(const MarkerKey& key) const {
  for (const MapMarker& m : markers) {
    if (m.key == key) return &m;
  }
  return nullptr;
}

MapMarker* MarkerMap::Find(const MarkerKey& key) {
  for (MapMarker& m : markers) {
    if (m.key == key) return &m;
  }
  return nullptr;
}

const char* CameraModelName(CameraModel model) {
  switch (model) {
    case CameraModel::kPinholeRadtan:
      return "pinhole-radtan";
    case CameraModel::kPinholeEquidistant:
      return "pinhole-equidistant";
  }
  return "unknown";
}

std::optional<CameraModel> ParseCameraModel(const std::string& name) {
  if (name == "pinhole-radtan") return CameraModel::kPinholeRadtan;
  if (name == "pinhole-equidistant") return CameraModel::kPinholeEquidistant;
  return std::nullopt;
}

void ReadWarnings::Add(const std::string& reason, const std::string& message) {
  ++counts[reason];
  if (first_messages.size() < 20) first_messages.push_back(message);
}

long ReadWarnings::Total() const {
  long total = 0;
  for (const auto& [reason, n] : counts) total += n;
  return total;
}

std::optional<double> Dataset::MarkerSize(const MarkerKey& key) const {
  if (known_markers) {
    if (const MapMarker* m = known_markers->Find(key); m != nullptr && m->size_m > 0.0) return m->size_m;
  }
  return config.default_marker_size_m;
}

}  // namespace waymark
