#pragma once
// LED pairs of a dataset (docs/formats.md, images.csv: a row whose path ends in -on.<ext> and,
// next for its camera, the same path ending in -off.<ext>) and the square detector's settings
// from the dataset, for `waymark detect DATASET --families square`.
#include <optional>
#include <string>
#include <vector>

#include "detect/square.h"
#include "io/dataset_io.h"

namespace waymark::cli {

struct LedPair {
  ImageEntry on;
  ImageEntry off;
};

// Splits rows (in stamp order) into LED pairs and the other rows. Throws std::runtime_error
// naming `where` (the images.csv) and the image for an on row whose camera's next row is not
// its off partner, and for an off row without its on row.
void SplitLedPairs(const std::vector<ImageEntry>& rows, const std::string& where, std::vector<LedPair>* pairs,
                   std::vector<ImageEntry>* others);

// The square detector's options for `camera`: the side and tape of the dataset's squares
// (markers.json; they must all be alike) and their height above the camera. Throws
// std::runtime_error naming the dataset when markers.json has no square with a pose, or squares
// of different sides or tapes.
SquareDetectorOptions SquareOptionsFor(const Dataset& dataset, const CameraInfo& camera);

// The one square of the dataset's markers.json with a pose, if there is exactly one: detections
// then get its id (and its corner order); with several, the localizer tells them apart.
const MapMarker* OnlySquare(const Dataset& dataset);

}  // namespace waymark::cli
