#pragma once
// Detection on a dataset's own images (images.csv) for the commands that take a dataset
// (`waymark map build/merge --detect-images`): the same detections `waymark detect DATASET`
// writes, kept in memory instead of read back from detections.jsonl.
#include <functional>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "cli/args.h"
#include "detect/detector.h"
#include "io/dataset_io.h"

namespace waymark::cli {

// The families `waymark detect` and `--detect-images` detect unless told otherwise.
inline constexpr const char* kDefaultDetectFamilies = "qr,datamatrix,apriltag-36h11";

// `--threads N` of the commands that detect (`detect`, `map build --detect-images`, `demo`):
// the multi-family detector's threads per frame (DetectorOptions::threads), by default the
// machine's cores. The detections do not depend on it. Throws std::invalid_argument for N
// outside 1..256.
int DetectionThreads(const Args& args);

// Throws std::runtime_error naming `what` when the image's size differs from the camera's.
void CheckImageMatchesCamera(const cv::Mat& image, const CameraInfo& camera, const std::string& what);

// The dataset's images.csv rows in stamp order (stable): detections.jsonl wants stamps that
// never decrease per camera.
std::vector<ImageEntry> ImageRowsInStampOrder(const Dataset& dataset);

// One DetectionFrame per images.csv row, in stamp order (stable), each with its row's stamp,
// camera and path. Throws std::runtime_error naming the image when it cannot be read or its
// size differs from its camera's (CheckImageMatchesCamera), and when the dataset has no
// images.csv rows.
// `progress(done, total)` is called after every image when set.
std::vector<DetectionFrame> DetectDatasetImages(
    const Dataset& dataset, MarkerDetector* detector,
    const std::function<void(size_t, size_t)>& progress = nullptr);

// The dataset's detections, checked for use by a map build: with `detect_images`, detected on
// its images (families as given, or every supported family); without, its detections.jsonl.
// Throws std::runtime_error naming the dataset when there is nothing to map: only images and
// no `--detect-images`, or not one code detected. `threads`: DetectorOptions::threads.
void PrepareDetectionsForMapping(bool detect_images, const std::vector<std::string>& families,
                                 Dataset* dataset, int threads = 1);

}  // namespace waymark::cli
