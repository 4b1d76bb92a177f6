// `waymark detect INPUT --out detections.jsonl`: runs the code detectors (detect/detector.h)
// on an image, a directory of images, a dataset directory (its images.csv) or a video,
// and writes detections.jsonl (io/detections_io.h) atomically: one line per image or
// frame. Progress goes to stderr on a terminal; a per-frame timing summary at the end.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <numeric>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "cli/dataset_detect.h"
#include "cli/led_pairs.h"
#include "detect/common.h"
#include "detect/detector.h"
#include "detect/square.h"
#include "geometry/square_marker.h"
#include "io/camera_io.h"
#include "io/dataset_io.h"
#include "io/detections_io.h"
#include "io/util.h"
#include "runner/image.h"
#include "util/stats.h"

namespace waymark::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kUsage = R"(Usage:
  waymark detect INPUT --out detections.jsonl [--camera cam.yaml]
                 [--families qr,datamatrix,apriltag-36h11] [--annotate DIR]
                 [--max-candidates 8] [--apriltag-decimate 8] [--threads N]
                 [--families-at-once]

Detects printed codes and writes one JSON line per image or video frame (docs/design.md
detections.jsonl; frames without codes get a line too). INPUT is
  - an image file: one line with "image": INPUT;
  - a directory of images (.png .jpg .jpeg .bmp .tif .tiff .webp .pgm .ppm), by name;
  - a dataset directory (with dataset.yaml): the rows of its images.csv, each with its
    row's stamp and camera;
  - a video file (.mp4 .avi .mkv .mov .webm .m4v .mpg .mpeg): "frame": N from 0, stamps
    from the video's clock.
Family square (the large square ceiling marker of reflective tape, [Seki]) is found in the
LED pairs of a dataset (images.csv rows ending -on.<ext> and -off.<ext>, docs/formats.md) by
detect/square.h; its side, tape and height come from the dataset's markers.json. A pair
gives one line at the on image's stamp; with one square in markers.json the detection gets its
id, with several the id "*" (the localizer tells them apart by its pose).
Image inputs get t = 0 (photos have no time) unless they come from a dataset.

Options:
  --out FILE          detections.jsonl to write (atomically; nothing on error)
  --camera FILE       camera YAML: its name goes into every line and every image must
                      have its size (default camera name: cam0)
  --families LIST     comma-separated families (default qr,datamatrix,apriltag-36h11);
                      any of: qr, datamatrix, apriltag-{16h5,25h9,36h10,36h11,circle21h7,
                      circle49h12,custom48h12,standard41h12,standard52h13}, square
  --annotate DIR      also write each image with its detections drawn (PNG), corner 0
                      (top-left of the upright code) marked
  --max-candidates N  candidate regions per frame the QR/DataMatrix second passes try (8);
                      work is bounded by counts, never by time: the same images give the
                      same detections on any machine and at any load
  --apriltag-decimate F   libapriltag quad_decimate of the whole frame (8), at most
                      that of the crops around candidate tag borders
  --threads N         threads per frame: the families run at the same time (default: the
                      machine's cores); the detections do not depend on N
  --families-at-once  every family on the whole frame at once, none skipping the places
                      another has read: more CPU time per frame, but on two or more idle
                      cores often less wall time (docs/detection.md); by default QR's
                      first pass, then the others, then QR's second passes, each skipping
                      the codes read before it

Exit status 0 on success; 1 with one line on stderr for a corrupt image, an unreadable
video, an empty directory or bad options.
)";

const std::set<std::string> kImageExtensions = {".png",  ".jpg",  ".jpeg", ".bmp", ".tif",
                                                ".tiff", ".webp", ".pgm",  ".ppm"};
const std::set<std::string> kVideoExtensions = {".mp4",  ".avi", ".mkv", ".mov",
                                                ".webm", ".m4v", ".mpg", ".mpeg"};

std::string LowerExtension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

// One image to process.
struct ImageJob {
  fs::path file;         // where to read it
  std::string as_given;  // written as "image"
  double stamp_s = 0.0;
  std::string camera;
};

struct RunOptions {
  std::string default_camera = "cam0";
  std::optional<CameraInfo> camera;  // --camera
  std::optional<fs::path> annotate_dir;
};

// Per-frame wall-clock times and totals, summarized on stderr at the end.
struct Timing {
  std::vector<double> frame_ms;
  std::vector<double> cpu_ms;  // CPU time of the process (every thread) per frame
  long markers = 0;

  std::string Summary() const {
    std::vector<double> sorted = frame_ms;
    std::sort(sorted.begin(), sorted.end());
    const double mean =
        std::accumulate(sorted.begin(), sorted.end(), 0.0) / std::max<size_t>(sorted.size(), 1);
    const double median = sorted.empty() ? 0.0 : QuantileOfSorted(sorted, 0.5);
    return "detect: " + std::to_string(sorted.size()) + " frames, " + std::to_string(markers) +
           " markers; detection time per frame: mean " + FormatFixed(mean, 1) + " ms, median " +
           FormatFixed(median, 1) + " ms, max " + FormatFixed(sorted.empty() ? 0.0 : sorted.back(), 1) +
           " ms; CPU time per frame (all threads): mean " +
           FormatFixed(
               std::accumulate(cpu_ms.begin(), cpu_ms.end(), 0.0) / std::max<size_t>(cpu_ms.size(), 1), 1) +
           " ms";
  }
};

void ShowProgress(size_t done, long total) {
  if (!StderrIsTerminal()) return;
  std::cerr << "\rdetect: " << done;
  if (total > 0) std::cerr << "/" << total;
  std::cerr << " frames" << std::flush;
}

// Annotated copies are written to a staging directory and moved into place only when the
// whole run succeeds, so an error leaves nothing half-written there either; directories the
// run created (DIR itself, missing parents) are removed again on error when left empty.
class Annotator {
 public:
  explicit Annotator(std::optional<fs::path> dir) : dir_(std::move(dir)) {
    if (!dir_) return;
    for (fs::path p = fs::absolute(*dir_); !p.empty() && !fs::exists(p); p = p.parent_path()) {
      created_.push_back(p);  // deepest first
      if (p == p.parent_path()) break;
    }
    RemoveStaleTemporaryDirectories(*dir_, ".partial-");  // of a killed `waymark detect`
    staging_ = *dir_ / (".partial-" + std::to_string(::getpid()));
    fs::create_directories(staging_);
  }
  ~Annotator() {
    std::error_code ignored;
    if (!staging_.empty()) fs::remove_all(staging_, ignored);
    if (committed_) return;
    for (const fs::path& p : created_) fs::remove(p, ignored);  // only if empty
  }
  Annotator(const Annotator&) = delete;
  Annotator& operator=(const Annotator&) = delete;

  void Add(const cv::Mat& image, const std::vector<MarkerObservation>& markers, const std::string& name) {
    if (!dir_) return;
    cv::Mat canvas;
    if (image.channels() == 1) {
      cv::cvtColor(image, canvas, cv::COLOR_GRAY2BGR);
    } else if (image.channels() == 4) {
      cv::cvtColor(image, canvas, cv::COLOR_BGRA2BGR);
    } else {
      canvas = image.clone();
    }
    for (const MarkerObservation& m : markers) Draw(m, &canvas);
    const fs::path file = staging_ / (name + ".png");
    if (!cv::imwrite(file.string(), canvas)) throw std::runtime_error(file.string() + ": cannot write image");
    names_.push_back(name + ".png");
  }

  void Commit() {
    if (!dir_) return;
    for (const std::string& name : names_) fs::rename(staging_ / name, *dir_ / name);
    committed_ = true;
  }

 private:
  static void Draw(const MarkerObservation& m, cv::Mat* canvas) {
    std::vector<cv::Point> quad;
    for (const auto& c : m.corners_px) quad.emplace_back(cvRound(c.x()), cvRound(c.y()));
    cv::polylines(*canvas, quad, true, cv::Scalar(0, 200, 0), 2);
    cv::circle(*canvas, quad[0], 5, cv::Scalar(0, 0, 255), 2);
    cv::putText(*canvas, m.key.ToString(), quad[0] + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(255, 0, 0), 1);
  }

  std::optional<fs::path> dir_;
  fs::path staging_;
  std::vector<fs::path> created_;  // directories this run created, deepest first
  bool committed_ = false;
  std::vector<std::string> names_;
};

DetectionFrame DetectOne(MarkerDetector* detector, const cv::Mat& image, Timing* timing) {
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = FrameClock::ProcessCpuMs();
  DetectionFrame frame;
  frame.markers = detector->Detect(image);
  timing->frame_ms.push_back(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  timing->cpu_ms.push_back(FrameClock::ProcessCpuMs() - cpu_start);
  timing->markers += static_cast<long>(frame.markers.size());
  return frame;
}

std::vector<DetectionFrame> RunImages(const std::vector<ImageJob>& jobs, MarkerDetector* detector,
                                      const std::map<std::string, CameraInfo>& cameras, Annotator* annotator,
                                      Timing* timing) {
  std::vector<DetectionFrame> frames;
  for (size_t i = 0; i < jobs.size(); ++i) {
    const ImageJob& job = jobs[i];
    std::string why;
    const cv::Mat image = ReadImageFile(job.file, &why);
    if (image.empty()) throw std::runtime_error(why);
    const auto camera = cameras.find(job.camera);
    if (camera != cameras.end()) CheckImageMatchesCamera(image, camera->second, job.file.string());
    DetectionFrame frame = DetectOne(detector, image, timing);
    frame.stamp_s = job.stamp_s;
    frame.camera = job.camera;
    frame.image = job.as_given;
    annotator->Add(image, frame.markers, std::to_string(i) + "_" + job.file.stem().string());
    frames.push_back(std::move(frame));
    ShowProgress(i + 1, static_cast<long>(jobs.size()));
  }
  return frames;
}

// A video file through FFmpeg only. With CAP_ANY, OpenCV tries every backend on a file FFmpeg
// cannot open: GStreamer printed an OpenCV assertion beside our one-line error, and a camera
// backend's device probe (libusb) leaked 22 kB that AddressSanitizer reports (issue 18's sanitizer
// suite, `DetectCli.BadInputsFailWithOneLineAndNoOutput`). FFmpeg's own messages ("moov atom not
// found") are silenced through OpenCV's OPENCV_FFMPEG_LOGLEVEL (read when its FFmpeg wrapper
// starts; a value the user set is kept). Where OpenCV was built without FFmpeg, any backend.
cv::VideoCapture OpenVideo(const fs::path& path) {
  if (!cv::videoio_registry::hasBackend(cv::CAP_FFMPEG)) return cv::VideoCapture(path.string());
  setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", /*overwrite=*/0);  // AV_LOG_QUIET
  return cv::VideoCapture(path.string(), cv::CAP_FFMPEG);
}

std::vector<DetectionFrame> RunVideo(const fs::path& path, const std::string& as_given,
                                     MarkerDetector* detector, const RunOptions& run, Annotator* annotator,
                                     Timing* timing) {
  cv::VideoCapture video = OpenVideo(path);
  if (!video.isOpened()) throw std::runtime_error(as_given + ": cannot open video");
  const long total = static_cast<long>(video.get(cv::CAP_PROP_FRAME_COUNT));
  std::vector<DetectionFrame> frames;
  cv::Mat image;
  for (long n = 0; video.read(image); ++n) {
    if (image.empty()) break;
    if (run.camera) CheckImageMatchesCamera(image, *run.camera, as_given + " frame " + std::to_string(n));
    DetectionFrame frame = DetectOne(detector, image, timing);
    frame.stamp_s = video.get(cv::CAP_PROP_POS_MSEC) * 1e-3;
    if (!frames.empty()) frame.stamp_s = std::max(frame.stamp_s, frames.back().stamp_s);
    frame.camera = run.camera ? run.camera->name : run.default_camera;
    frame.frame = n;
    std::ostringstream name;
    name << "frame_" << std::setw(6) << std::setfill('0') << n;
    annotator->Add(image, frame.markers, name.str());
    frames.push_back(std::move(frame));
    ShowProgress(frames.size(), total);
  }
  if (frames.empty()) throw std::runtime_error(as_given + ": no frame could be read from the video");
  return frames;
}

std::vector<ImageJob> ListImageDir(const fs::path& dir, const std::string& as_given,
                                   const std::string& camera) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file() && kImageExtensions.count(LowerExtension(entry.path())))
      files.push_back(entry.path());
  }
  if (files.empty())
    throw std::runtime_error(as_given + ": no images in directory (expected .png, .jpg, ...)");
  std::sort(files.begin(), files.end());
  std::vector<ImageJob> jobs;
  for (const fs::path& f : files)
    jobs.push_back({f, (fs::path(as_given) / f.filename()).string(), 0.0, camera});
  return jobs;
}

std::vector<ImageJob> ListDataset(const Dataset& dataset, const std::string& as_given) {
  if (dataset.images.empty())
    throw std::runtime_error(as_given + ": dataset has no images.csv rows to detect on");
  std::vector<ImageJob> jobs;
  for (const ImageEntry& row : ImageRowsInStampOrder(dataset)) {
    jobs.push_back({dataset.dir / row.path, row.path, row.stamp_s, row.camera});
  }
  return jobs;
}

// The code detector for the families other than square (nullptr if there are none);
// *square is set when the list has square.
std::unique_ptr<MarkerDetector> MakeDetector(const Args& args, bool* square) {
  DetectorOptions options;
  if (const auto regions = args.GetInt("max-candidates")) {
    if (*regions < 0 || *regions > 64) {
      throw std::invalid_argument("--max-candidates: expected 0..64, got " + std::to_string(*regions));
    }
    options.max_candidates = static_cast<int>(*regions);
  }
  if (const auto decimate = args.GetDouble("apriltag-decimate")) options.apriltag_decimate = *decimate;
  options.threads = DetectionThreads(args);
  options.family_steps = !args.Flag("families-at-once");
  const std::string list = args.GetOr("families", kDefaultDetectFamilies);
  std::string others;
  *square = false;
  std::stringstream stream(list);
  for (std::string item; std::getline(stream, item, ',');) {
    if (item == kFamilySquare) {
      if (*square) throw std::invalid_argument("marker family 'square' repeated in '" + list + "'");
      *square = true;
    } else {
      others += (others.empty() ? "" : ",") + item;
    }
  }
  if (*square && others.empty()) {
    if (list.back() == ',' || list.front() == ',')
      throw std::invalid_argument("empty marker family in '" + list + "'");
    return nullptr;
  }
  return CreateMultiDetector(ParseFamilyList(others), options);
}

cv::Mat ReadImage(const fs::path& file) {
  const cv::Mat image = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (image.empty())
    throw std::runtime_error(file.string() + ": cannot read image (missing, corrupt or not an image)");
  return image;
}

cv::Mat Gray(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

// A dataset with family square: squares in its LED pairs, the other families (if any) in the
// on images and the unpaired rows.
std::vector<DetectionFrame> RunDatasetPairs(const Dataset& dataset, const std::string& input,
                                            MarkerDetector* detector, Annotator* annotator, Timing* timing) {
  std::vector<LedPair> pairs;
  std::vector<ImageEntry> others;
  const std::string images_csv = (dataset.dir / dataset.config.images_file).string();
  if (dataset.images.empty())
    throw std::runtime_error(input + ": dataset has no images.csv rows to detect on");
  SplitLedPairs(ImageRowsInStampOrder(dataset), images_csv, &pairs, &others);
  if (pairs.empty()) {
    throw std::runtime_error(images_csv +
                             ": no LED pairs (rows ending -on.<ext> and -off.<ext>) for family square");
  }
  const MapMarker* only = OnlySquare(dataset);
  std::map<std::string, SquareDetector> detectors;
  std::vector<DetectionFrame> frames;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const LedPair& pair = pairs[i];
    const fs::path on_file = dataset.dir / pair.on.path, off_file = dataset.dir / pair.off.path;
    const cv::Mat on = ReadImage(on_file), off = ReadImage(off_file);
    if (on.size() != off.size()) {
      throw std::runtime_error(on_file.string() + ": LED pair: the on image is " + std::to_string(on.cols) +
                               "x" + std::to_string(on.rows) + " but its off image " + pair.off.path +
                               " is " + std::to_string(off.cols) + "x" + std::to_string(off.rows));
    }
    const CameraInfo& camera = dataset.cameras.at(pair.on.camera);
    CheckImageMatchesCamera(on, camera, on_file.string());
    auto it = detectors.find(camera.name);
    if (it == detectors.end()) {
      it = detectors.emplace(camera.name, SquareDetector(Camera(camera), SquareOptionsFor(dataset, camera)))
               .first;
    }
    const auto start = std::chrono::steady_clock::now();
    DetectionFrame frame;
    for (const SquareDetection& found : it->second.Detect(Gray(on), Gray(off))) {
      MarkerObservation observation;
      observation.key = {kFamilySquare, only ? only->key.id : kUnidentifiedSquareId};
      observation.corners_px =
          only ? SolidFirstToMarkerOrder(found.corners_px, TapeOf(*only).solid_side) : found.corners_px;
      frame.markers.push_back(observation);
    }
    if (detector != nullptr) {
      for (MarkerObservation& m : detector->Detect(on)) frame.markers.push_back(std::move(m));
    }
    timing->frame_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    timing->markers += static_cast<long>(frame.markers.size());
    frame.stamp_s = pair.on.stamp_s;
    frame.camera = pair.on.camera;
    frame.image = pair.on.path;
    annotator->Add(on, frame.markers, std::to_string(i) + "_" + on_file.stem().string());
    frames.push_back(std::move(frame));
    ShowProgress(frames.size(), static_cast<long>(pairs.size() + (detector ? others.size() : 0)));
  }
  if (detector != nullptr && !others.empty()) {
    std::vector<ImageJob> jobs;
    for (const ImageEntry& row : others)
      jobs.push_back({dataset.dir / row.path, row.path, row.stamp_s, row.camera});
    for (DetectionFrame& f : RunImages(jobs, detector, dataset.cameras, annotator, timing))
      frames.push_back(std::move(f));
    std::stable_sort(frames.begin(), frames.end(),
                     [](const DetectionFrame& a, const DetectionFrame& b) { return a.stamp_s < b.stamp_s; });
  }
  return frames;
}

std::vector<DetectionFrame> RunInput(const std::string& input, MarkerDetector* detector, bool square,
                                     const RunOptions& run, Annotator* annotator, Timing* timing) {
  const fs::path path(input);
  std::map<std::string, CameraInfo> cameras;
  const std::string camera_name = run.camera ? run.camera->name : run.default_camera;
  if (run.camera) cameras[camera_name] = *run.camera;
  const bool is_dataset = fs::is_directory(path) && fs::exists(path / "dataset.yaml");
  if (square && !is_dataset) {
    throw std::runtime_error(input +
                             ": family square is detected in the LED pairs of a dataset (a directory with "
                             "dataset.yaml and images.csv)");
  }
  if (fs::is_directory(path)) {
    if (is_dataset) {
      const Dataset dataset = LoadDataset(path);
      if (square) return RunDatasetPairs(dataset, input, detector, annotator, timing);
      return RunImages(ListDataset(dataset, input), detector, dataset.cameras, annotator, timing);
    }
    return RunImages(ListImageDir(path, input, camera_name), detector, cameras, annotator, timing);
  }
  if (!fs::exists(path)) throw std::runtime_error(input + ": no such file or directory");
  if (kVideoExtensions.count(LowerExtension(path)))
    return RunVideo(path, input, detector, run, annotator, timing);
  return RunImages({{path, input, 0.0, camera_name}}, detector, cameras, annotator, timing);
}

int RunDetect(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"out", "camera", "families", "annotate", "max-candidates", "apriltag-decimate", "threads"},
                  {"families-at-once"});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "INPUT (an image, a directory, a dataset or a video)");
  // OpenCV's video back ends log warnings for unreadable files; our own message says it.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  const fs::path out = args.Require("out");
  RunOptions run;
  if (const auto camera = args.Get("camera")) run.camera = ReadCameraYaml(*camera);
  if (const auto dir = args.Get("annotate")) run.annotate_dir = fs::path(*dir);
  bool square = false;
  std::unique_ptr<MarkerDetector> detector = MakeDetector(args, &square);
  Annotator annotator(run.annotate_dir);
  Timing timing;
  const std::vector<DetectionFrame> frames =
      RunInput(args.positionals()[0], detector.get(), square, run, &annotator, &timing);
  if (StderrIsTerminal()) std::cerr << "\n";
  WriteDetections(out, frames);
  annotator.Commit();
  std::cerr << timing.Summary() << "\n";
  return 0;
}

const CommandRegistrar kRegistrar({"detect", "detect QR, DataMatrix and AprilTag codes in images or video",
                                   kUsage, RunDetect});

}  // namespace
}  // namespace waymark::cli
