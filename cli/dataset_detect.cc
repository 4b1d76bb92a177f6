#include "cli/dataset_detect.h"

#include <algorithm>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <thread>

#include "cli/command.h"
#include "runner/image.h"

namespace waymark::cli {

void CheckImageMatchesCamera(const cv::Mat& image, const CameraInfo& camera, const std::string& what) {
  if (image.cols != camera.width || image.rows != camera.height) {
    throw std::runtime_error(what + ": image is " + std::to_string(image.cols) + "x" +
                             std::to_string(image.rows) + " but camera " + camera.name + " is " +
                             std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
}

std::vector<ImageEntry> ImageRowsInStampOrder(const Dataset& dataset) {
  std::vector<ImageEntry> rows = dataset.images;
  std::stable_sort(rows.begin(), rows.end(),
                   [](const ImageEntry& a, const ImageEntry& b) { return a.stamp_s < b.stamp_s; });
  return rows;
}

std::vector<DetectionFrame> DetectDatasetImages(const Dataset& dataset, MarkerDetector* detector,
                                                const std::function<void(size_t, size_t)>& progress) {
  if (dataset.images.empty()) {
    throw std::runtime_error("dataset " + dataset.dir.string() + ": no images.csv rows to detect on");
  }
  const std::vector<ImageEntry> rows = ImageRowsInStampOrder(dataset);
  std::vector<DetectionFrame> frames;
  frames.reserve(rows.size());
  for (const ImageEntry& row : rows) {
    const std::string file = (dataset.dir / row.path).string();
    std::string why;
    const cv::Mat image = ReadImageFile(file, &why);
    if (image.empty()) throw std::runtime_error(why);
    // The dataset reader checked that images.csv names only cameras of dataset.yaml.
    CheckImageMatchesCamera(image, dataset.cameras.at(row.camera), file);
    DetectionFrame frame;
    frame.stamp_s = row.stamp_s;
    frame.camera = row.camera;
    frame.image = row.path;
    frame.markers = detector->Detect(image);
    frames.push_back(std::move(frame));
    if (progress) progress(frames.size(), rows.size());
  }
  return frames;
}

int DetectionThreads(const Args& args) {
  const auto n = args.GetInt("threads");
  if (!n) return static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 256u));
  if (*n < 1 || *n > 256)
    throw std::invalid_argument("--threads: expected 1..256, got " + std::to_string(*n));
  return static_cast<int>(*n);
}

void PrepareDetectionsForMapping(bool detect_images, const std::vector<std::string>& families,
                                 Dataset* dataset, int threads) {
  const std::string where = "dataset " + dataset->dir.string();
  if (detect_images) {
    const std::vector<std::string> used =
        families.empty() ? ParseFamilyList(kDefaultDetectFamilies) : families;
    DetectorOptions options;
    options.threads = threads;
    const std::unique_ptr<MarkerDetector> detector = CreateMultiDetector(used, options);
    std::function<void(size_t, size_t)> progress;
    if (StderrIsTerminal()) {
      progress = [](size_t done, size_t total) {
        std::cerr << "\r\033[Kdetect: " << done << "/" << total << std::flush;
      };
    }
    dataset->detections = DetectDatasetImages(*dataset, detector.get(), progress);
    if (progress) std::cerr << "\r\033[K";
  } else if (dataset->detections.empty() && !dataset->images.empty()) {
    throw std::runtime_error(where +
                             ": no detections.jsonl, only images: detect on them (--detect-images, or "
                             "`waymark detect` first)");
  }
  const bool any_code = std::any_of(dataset->detections.begin(), dataset->detections.end(),
                                    [](const DetectionFrame& f) { return !f.markers.empty(); });
  if (!any_code) {
    throw std::runtime_error(where + (detect_images ? ": no code detected on its " +
                                                          std::to_string(dataset->images.size()) + " images"
                                                    : ": its detections hold no code"));
  }
}

}  // namespace waymark::cli
