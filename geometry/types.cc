#include "geometry/types.h"

#include <algorithm>

namespace waymark {

bool IsKnownFamily(const std::string& family) {
  if (family == kFamilyQr || family == kFamilyDataMatrix || family == kFamilySquare) return true;
  const std::string prefix = kFamilyAprilTagPrefix;
  return family.size() > prefix.size() && family.compare(0, prefix.size(), prefix) == 0;
}

bool IsPointFamily(const std::string& family) { return family == kFamilyBarcode || IsKnownFamily(family); }

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
    case CameraModel::kEquisolid:
      return "equisolid";
  }
  return "unknown";
}

std::optional<CameraModel> ParseCameraModel(const std::string& name) {
  if (name == "pinhole-radtan") return CameraModel::kPinholeRadtan;
  if (name == "pinhole-equidistant") return CameraModel::kPinholeEquidistant;
  if (name == "equisolid") return CameraModel::kEquisolid;
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

long SampleAtOrBefore(const Trajectory& trajectory, double stamp_s) {
  const auto it = std::upper_bound(trajectory.begin(), trajectory.end(), stamp_s,
                                   [](double s, const StampedSE3& p) { return s < p.stamp_s; });
  return static_cast<long>(it - trajectory.begin()) - 1;
}

std::optional<SE3d> InterpolateTrajectory(const Trajectory& trajectory, double stamp_s, double max_gap_s) {
  const long i = SampleAtOrBefore(trajectory, stamp_s);
  if (i < 0) return std::nullopt;
  if (trajectory[i].stamp_s == stamp_s) return trajectory[i].T;
  if (i + 1 >= static_cast<long>(trajectory.size())) return std::nullopt;
  const StampedSE3& a = trajectory[i];
  const StampedSE3& b = trajectory[i + 1];
  if (b.stamp_s - a.stamp_s > max_gap_s) return std::nullopt;
  return InterpolateProduct(a.T, b.T, (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s));
}

}  // namespace waymark
