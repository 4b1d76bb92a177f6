// Detection benchmark: decode rates on the real photos of ../shared/data/codes and
// per-frame times on synthetic 1280x960 frames, one thread.
//
//   bench_detection_bench [--report-only] [--no-write] [google benchmark flags]
//   bench_detection_bench --help
//
// Plain report (stdout, and bench/results/detection.json written atomically):
//   - per photo set: images whose expected text (NN.txt, or bytes NN.bin) is among the
//     detected ids, with Waymark's detector (default options) and with zxing-cpp alone
//     (one full-image pass); detections on falsepositives-1 with qr+datamatrix+apriltag;
//   - per family and 0, 1, 4 codes per frame: median and max wall time and mean thread
//     CPU time of Detect() over synthetic frames (cluttered background, fixed seed), and
//     the codes decoded;
//   - all three families at once (CreateMultiDetector) on 1 and 2 threads, the codes of the
//     three families mixed: mean CPU time of the process per frame, median wall time.
// Then Google Benchmark runs the same frames (BM_Detect/<family>/<codes>) unless
// --report-only is given. --no-write prints the report without writing the JSON file (a
// measurement on a loaded machine); an unknown flag is an error before anything runs.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "detect/common.h"
#include "detect/detector.h"
#include "detect/synthetic.h"
#include "detect/zxing.h"
#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

const fs::path kCodes = fs::path(WAYMARK_SHARED_DATA) / "codes";
const std::vector<std::string> kTimedFamilies = {"qr", "datamatrix", "apriltag-36h11"};

std::string Slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

bool IsImage(const fs::path& p) {
  const std::string ext = p.extension().string();
  return ext == ".png" || ext == ".jpg" || ext == ".webp";
}

// True if one of `ids` is the expected payload: the text of NN.txt, or the bytes of NN.bin
// (compared raw, and as ISO-8859-1 re-encoded to UTF-8 the way TextToId does).
bool Matches(const std::vector<std::string>& ids, const fs::path& image) {
  fs::path txt = image, bin = image;
  txt.replace_extension(".txt");
  bin.replace_extension(".bin");
  std::vector<std::string> expected;
  if (fs::exists(bin)) {
    expected = {Slurp(bin), TextToId(Slurp(bin))};
  } else if (fs::exists(txt)) {
    expected = {Slurp(txt)};
  }
  for (const auto& id : ids) {
    if (std::find(expected.begin(), expected.end(), id) != expected.end()) return true;
  }
  return false;
}

std::vector<fs::path> Images(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (IsImage(e.path())) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

nlohmann::json EvaluateSet(const std::string& set, const std::string& family) {
  auto detector = CreateDetector(family);
  const ZxingSymbology symbology = family == "qr" ? ZxingSymbology::kQrCode : ZxingSymbology::kDataMatrix;
  int images = 0, ours = 0, zxing = 0;
  std::vector<std::string> missed;
  for (const fs::path& file : Images(kCodes / set)) {
    const cv::Mat gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (gray.empty()) continue;
    ++images;
    std::vector<std::string> ids, zx_ids;
    for (const auto& m : detector->Detect(gray)) ids.push_back(m.key.id);
    for (const auto& m : ReadWithZxing(gray, symbology, ZxingPass{})) zx_ids.push_back(m.key.id);
    const bool ok = Matches(ids, file);
    ours += ok;
    zxing += Matches(zx_ids, file);
    if (!ok) missed.push_back(file.filename().string());
  }
  std::cout << "  " << set << ": " << ours << "/" << images << " (zxing-cpp alone " << zxing << ")\n";
  return {{"set", set},      {"family", family},     {"images", images},
          {"decoded", ours}, {"zxing_alone", zxing}, {"missed", missed}};
}

nlohmann::json EvaluateFalsePositives() {
  auto detector = CreateMultiDetector(kTimedFamilies);
  int images = 0, detections = 0, unreadable = 0;
  for (const fs::path& file : Images(kCodes / "falsepositives-1")) {
    const cv::Mat gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (gray.empty()) {
      ++unreadable;  // 1x1 and 1x100 webp files that OpenCV 4.6 cannot decode
      continue;
    }
    ++images;
    detections += static_cast<int>(detector->Detect(gray).size());
  }
  std::cout << "  falsepositives-1: " << detections << " detections on " << images << " images ("
            << unreadable << " unreadable by OpenCV)\n";
  return {{"set", "falsepositives-1"},
          {"images", images},
          {"unreadable", unreadable},
          {"detections", detections}};
}

// A 1280x960 indoor-like frame: a lit gradient, boxes, text lines and sensor noise.
cv::Mat Background(uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat frame(960, 1280, CV_8U);
  for (int y = 0; y < frame.rows; ++y) {
    for (int x = 0; x < frame.cols; ++x)
      frame.at<uint8_t>(y, x) = static_cast<uint8_t>(110 + 60 * x / 1280 + 20 * y / 960);
  }
  for (int i = 0; i < 30; ++i) {
    const cv::Rect box(rng.uniform(0, 1200), rng.uniform(0, 900), rng.uniform(20, 260), rng.uniform(20, 260));
    cv::rectangle(frame, box, cv::Scalar(rng.uniform(30, 230)), rng.uniform(0, 2) ? cv::FILLED : 3);
  }
  for (int i = 0; i < 12; ++i) {
    cv::putText(frame, "EXIT 12 Waymark aisle B", cv::Point(rng.uniform(0, 1000), rng.uniform(30, 950)),
                cv::FONT_HERSHEY_SIMPLEX, rng.uniform(0.5, 1.5), cv::Scalar(rng.uniform(0, 80)), 2);
  }
  return frame;
}

SymbolImage Symbol(const std::string& family, int i) {
  if (family == "qr") return QrSymbol("0/" + std::to_string(i) + "/12.5");
  if (family == "datamatrix") return DataMatrixSymbol("A0" + std::to_string(i));
  return AprilTagSymbol(family, i);
}

// `codes` codes of `family` ("mixed": qr, datamatrix, apriltag-36h11 in turn) at fixed places, sizes 150-210
// px, rotations 0.1-2.6 rad.
cv::Mat Frame(const std::string& family, int codes) {
  cv::Mat frame = Background(17);
  const Eigen::Vector2d centers[4] = {{300, 260}, {960, 250}, {330, 700}, {950, 690}};
  for (int i = 0; i < codes; ++i) {
    const Quad2d quad = MakeQuad(centers[i], 150.0 + 20 * i, 0.1 + 0.8 * i, 0.9);
    // A white card behind each code (quiet zone), as printed codes have.
    DrawSymbol({cv::Mat(1, 1, CV_8U, cv::Scalar(255)), cv::Rect(0, 0, 1, 1)},
               MakeQuad(centers[i], 1.4 * (150.0 + 20 * i), 0.1 + 0.8 * i, 0.9), &frame);
    DrawSymbol(Symbol(family == "mixed" ? kTimedFamilies[i % kTimedFamilies.size()] : family, i), quad,
               &frame);
  }
  cv::GaussianBlur(frame, frame, cv::Size(0, 0), 0.6);
  cv::RNG rng(5);
  AddSensorNoise(rng, 3.0, &frame);
  return frame;
}

nlohmann::json TimeFamily(const std::string& family, int codes, int repeats) {
  cv::Mat frame = Frame(family, codes);
  auto detector = CreateDetector(family);
  std::vector<double> wall_ms;
  double cpu_ms = 0.0;
  size_t found = 0;
  for (int r = 0; r < repeats; ++r) {
    // A new frame each time (one corner pixel differs): the candidate stage keeps its last
    // result for the same pixels (detect/quads.h), which a camera never gives twice.
    frame.at<uint8_t>(0, 0) = static_cast<uint8_t>(r);
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = FrameClock::ThreadCpuMs();
    found = detector->Detect(frame).size();
    cpu_ms += FrameClock::ThreadCpuMs() - cpu_start;
    wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(wall_ms.begin(), wall_ms.end());
  const double median = wall_ms[wall_ms.size() / 2];
  std::cout << "  " << family << " " << codes << " codes: median " << median << " ms, max " << wall_ms.back()
            << " ms, mean CPU " << cpu_ms / repeats << " ms, decoded " << found << "/" << codes << "\n";
  return {{"family", family},
          {"codes", codes},
          {"median_ms", median},
          {"max_ms", wall_ms.back()},
          {"mean_cpu_ms", cpu_ms / repeats},
          {"decoded", found},
          {"repeats", repeats}};
}

// All three families at once (CreateMultiDetector) on `threads` threads: mean CPU time per frame
// of the whole process (every thread; with one thread that is the thread's), median wall time.
nlohmann::json TimeAllFamilies(int codes, int threads, int repeats) {
  cv::Mat frame = Frame("mixed", codes);
  DetectorOptions options;
  options.threads = threads;
  auto detector = CreateMultiDetector(kTimedFamilies, options);
  std::vector<double> wall_ms;
  double cpu_ms = 0.0;
  size_t found = 0;
  for (int r = 0; r < repeats; ++r) {
    frame.at<uint8_t>(0, 0) = static_cast<uint8_t>(r);  // a new frame (as in TimeFamily)
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = FrameClock::ProcessCpuMs();
    found = detector->Detect(frame).size();
    cpu_ms += FrameClock::ProcessCpuMs() - cpu_start;
    wall_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(wall_ms.begin(), wall_ms.end());
  const double median = wall_ms[wall_ms.size() / 2];
  std::cout << "  all families, " << codes << " codes, " << threads << " thread(s): median wall " << median
            << " ms, mean CPU " << cpu_ms / repeats << " ms, decoded " << found << "/" << codes << "\n";
  return {{"codes", codes},           {"threads", threads},
          {"median_wall_ms", median}, {"mean_cpu_ms", cpu_ms / repeats},
          {"decoded", found},         {"repeats", repeats}};
}

void Report(bool write) {
  nlohmann::json out;
  double load[3] = {0, 0, 0};
  getloadavg(load, 3);
  out["load_average_1min"] = load[0];
  if (fs::exists(kCodes)) {
    std::cout << "Real photos (" << kCodes.string() << "), images decoded with the right text:\n";
    for (int i = 1; i <= 6; ++i) out["photos"].push_back(EvaluateSet("qrcode-" + std::to_string(i), "qr"));
    for (int i = 1; i <= 3; ++i)
      out["photos"].push_back(EvaluateSet("datamatrix-" + std::to_string(i), "datamatrix"));
    out["false_positives"] = EvaluateFalsePositives();
  } else {
    std::cout << "Real photos: " << kCodes.string() << " absent, skipped\n";
  }
  std::cout << "Synthetic 1280x960 frames, one thread (load average " << load[0] << "):\n";
  for (const std::string& family : kTimedFamilies) {
    for (int codes : {0, 1, 4}) out["timing"].push_back(TimeFamily(family, codes, 15));
  }
  std::cout << "All families at once (qr, datamatrix, apriltag-36h11; the codes mixed):\n";
  for (int threads : {1, 2}) {
    for (int codes : {0, 1, 4}) out["all_families"].push_back(TimeAllFamilies(codes, threads, 15));
  }
  if (!write) return;
  const fs::path json = fs::path(WAYMARK_SOURCE_DIR) / "bench" / "results" / "detection.json";
  AtomicWriteFile(json, out.dump(2) + "\n");
  std::cout << "wrote " << json.string() << "\n";
}

void BM_Detect(benchmark::State& state, const std::string& family, int codes) {
  const cv::Mat frame = Frame(family, codes);
  auto detector = CreateDetector(family);
  size_t found = 0;
  for (auto _ : state) {
    found = detector->Detect(frame).size();
    benchmark::DoNotOptimize(found);
  }
  state.counters["decoded"] = static_cast<double>(found);
}

}  // namespace
}  // namespace waymark

int main(int argc, char** argv) {
  cv::setNumThreads(1);  // one core: OpenCV's own worker threads off (wall and CPU time comparable)
  bool report_only = false, write = true;
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      std::cout << "Usage: bench_detection_bench [--report-only] [--no-write] [google benchmark flags]\n"
                   "Decode rates on ../shared/data/codes and per-frame times on synthetic frames;\n"
                   "writes bench/results/detection.json unless --no-write, then runs Google\n"
                   "Benchmark unless --report-only.\n";
      return 0;
    }
    if (arg == "--report-only") {
      report_only = true;
    } else if (arg == "--no-write") {
      write = false;
    } else {
      rest.push_back(argv[i]);
    }
  }
  // Google Benchmark's flags are checked before anything runs or is written.
  int rest_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&rest_argc, rest.data());
  if (benchmark::ReportUnrecognizedArguments(rest_argc, rest.data())) return 1;
  waymark::Report(write);
  if (report_only) return 0;
  for (const std::string& family : waymark::kTimedFamilies) {
    for (int codes : {0, 1, 4}) {
      benchmark::RegisterBenchmark(
          ("BM_Detect/" + family + "/" + std::to_string(codes)).c_str(),
          [family, codes](benchmark::State& s) { waymark::BM_Detect(s, family, codes); })
          ->Unit(benchmark::kMillisecond);
    }
  }
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
