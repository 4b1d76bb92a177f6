// Which square each `square` detection of a survey is ([Seki]; geometry/square_marker.h). The
// squares carry no id: `waymark detect --families square` writes the id "*" (several squares in
// markers.json) or the name of markers.json's only square, whichever square it actually saw. Before
// the map build the detections are told apart by where the odometry puts them:
//
//   The robot pose T_w_r (world of markers.json's squares, else the robot's frame at the first
//   sighting) starts at the survey's first near sighting (the square's centre within one side of
//   the robot; a steep view's single-image pose can be decimetres and degrees off): that square is
//   the one the detection names if markers.json has it with a pose, else markers.json's first
//   square with a pose, else a new square S0 (then the map's gauge is the build's usual one,
//   docs/mapping.md). From there T_w_r moves with the odometry's increments (backwards before
//   it); at every near sighting the square's centre is predicted from the single-image pose
//   (geometry/marker_pose.h): the known or already found square within half a side of it (the
//   nearest) re-anchors T_w_r's x, y and yaw; near none, it is a new square named S<n> with the
//   first n no square uses yet. Then every sighting, near or far, is the square nearest its
//   predicted centre within half a side; a sighting near none (a square never passed under) or
//   without a pose is left out (counted).
//
// The odometry's drift between two squares must stay under half a side (1 m for [Seki]'s 2 m
// squares); the squares must look alike (the detector's condition): one side and one tape, taken
// from markers.json's first square, else the dataset's default_marker_size_m and the default tape.
// Corners of "*" detections are put in the square's own corner order (SolidFirstToMarkerOrder).
#pragma once

#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

struct SquareAssociationStats {
  int sightings = 0;    // `square` detections associated
  int known_used = 0;   // markers.json squares seen
  int new_squares = 0;  // squares found by the survey
  int unplaced = 0;     // detections whose single-image pose failed (left out)
};

// True when the dataset has a `square` detection.
bool HasSquareDetections(const Dataset& dataset);

// The dataset with its `square` detections renamed as above and a size-only markers.json entry
// (with the tape) for every new square. Throws std::runtime_error (one line, naming the dataset)
// when the dataset has no odometry, or no square size (no markers.json square and no
// default_marker_size_m).
Dataset AssociateSquares(const Dataset& dataset, SquareAssociationStats* stats = nullptr);

}  // namespace waymark
