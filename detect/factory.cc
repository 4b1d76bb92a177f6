// DetectorOptions::Check, the family list and the factories of detect/detector.h.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "detect/apriltag.h"
#include "detect/common.h"
#include "detect/datamatrix.h"
#include "detect/detector.h"
#include "detect/qr.h"
#include "detect/quads.h"
#include "util/check.h"

namespace waymark {

bool DetectorOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(min_side_px >= 1.0, "min_side_px must be >= 1");
  WAYMARK_CHECK_OPTION(max_candidates >= 0, "max_candidates must be >= 0");
  WAYMARK_CHECK_OPTION(max_qr_finder_candidates >= 0, "max_qr_finder_candidates must be >= 0");
  WAYMARK_CHECK_OPTION(max_datamatrix_candidates >= 0, "max_datamatrix_candidates must be >= 0");
  WAYMARK_CHECK_OPTION(live_budget_ms >= 0.0 && std::isfinite(live_budget_ms), "live_budget_ms must be >= 0");
  WAYMARK_CHECK_OPTION(apriltag_decimate >= 1.0, "apriltag_decimate must be >= 1");
  WAYMARK_CHECK_OPTION(apriltag_blur_sigma >= 0.0, "apriltag_blur_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(apriltag_max_bits_corrected >= 0 && apriltag_max_bits_corrected <= 3,
                       "apriltag_max_bits_corrected must be in [0, 3]");
  WAYMARK_CHECK_OPTION(threads >= 1, "threads must be >= 1");
  return true;
}

std::vector<std::string> SupportedFamilies() {
  std::vector<std::string> families = {kFamilyQr, kFamilyDataMatrix};
  for (const std::string& name : AprilTagFamilyNames()) families.push_back(kFamilyAprilTagPrefix + name);
  return families;
}

namespace {

void CheckOptions(const DetectorOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("detector options: " + why);
}

class MultiDetector : public MarkerDetector {
 public:
  MultiDetector(std::vector<std::unique_ptr<MarkerDetector>> detectors, const DetectorOptions& options)
      : detectors_(std::move(detectors)), options_(options) {}

  std::vector<std::string> Families() const override {
    std::vector<std::string> families;
    for (const auto& d : detectors_) {
      for (const std::string& f : d->Families()) families.push_back(f);
    }
    return families;
  }

  // The three steps of detect/detector.h (CreateMultiDetector).
  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const cv::Mat gray = ToGray8(image);   // convert once for every family
    const PixelHashScope hash_once(gray);  // the shared whole-frame work's cache key
    if (!options_.family_steps) return EachFamily([&gray](MarkerDetector& d) { return d.Detect(gray); });
    const size_t n = detectors_.size();
    std::vector<size_t> last, whole;  // families with SecondPassesLast, the others
    for (size_t i = 0; i < n; ++i) (detectors_[i]->SecondPassesLast() ? last : whole).push_back(i);
    std::vector<std::vector<MarkerObservation>> found(n);
    std::vector<int> skipped(n, 0);
    // No detector keeps a pointer to the lists below once Detect() returns or throws.
    const ClearReadByOthers clear{&detectors_};
    // 1: the first passes; beside them, on a thread of their own, the shared candidate stages
    // the later steps use (each a function of the pixels, cached per image: the results do not
    // depend on which thread computes them first).
    {
      const JoinedThread warm(options_.threads > 1 && !last.empty(),
                              [this, &gray] { WarmSharedStages(gray); });
      EachOf(
          last, [&gray](MarkerDetector& d) { return d.DetectFirstPass(gray); }, &found, &skipped,
          warm.running() ? options_.threads - 1 : options_.threads);
    }
    // 2: the other families, each given step 1's codes.
    std::vector<MarkerObservation> first_reads;
    for (const size_t i : last) AppendUnique(found[i], &first_reads);
    for (const size_t i : whole) detectors_[i]->SetReadByOthers(&first_reads);
    EachOf(
        whole, [&gray](MarkerDetector& d) { return d.Detect(gray); }, &found, &skipped);
    // 3: the second passes, each given every other family's codes.
    std::vector<std::vector<MarkerObservation>> others(n);
    for (const size_t i : last) {
      for (size_t j = 0; j < n; ++j) {
        if (j != i) AppendUnique(found[j], &others[i]);
      }
      detectors_[i]->SetReadByOthers(&others[i]);
    }
    EachOf(
        last, [](MarkerDetector& d) { return d.DetectSecondPasses(); }, &found, &skipped);
    return Merge(found, skipped);
  }

  std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) override {
    staged_gray_ = ToGray8(image);  // kept for the families' DetectSecondPasses()
    const PixelHashScope hash_once(staged_gray_);
    return EachFamily([this](MarkerDetector& d) { return d.DetectFirstPass(staged_gray_); });
  }

  std::vector<MarkerObservation> DetectSecondPasses() override {
    if (staged_gray_.empty())
      throw std::logic_error("detector: DetectSecondPasses() without DetectFirstPass()");
    const PixelHashScope hash_once(staged_gray_);
    return EachFamily([](MarkerDetector& d) { return d.DetectSecondPasses(); });
  }

  int SkippedAttempts() const override { return skipped_; }

 private:
  // A thread running `task` (when `start`), joined when this goes out of scope, also when an
  // exception leaves it.
  class JoinedThread {
   public:
    template <typename Task>
    JoinedThread(bool start, Task task) {
      if (start) thread_ = std::thread(std::move(task));
    }
    ~JoinedThread() {
      if (thread_.joinable()) thread_.join();
    }
    JoinedThread(const JoinedThread&) = delete;
    JoinedThread& operator=(const JoinedThread&) = delete;
    bool running() const { return thread_.joinable(); }

   private:
    std::thread thread_;
  };

  // Clears every detector's SetReadByOthers when it goes out of scope.
  struct ClearReadByOthers {
    std::vector<std::unique_ptr<MarkerDetector>>* detectors;
    ~ClearReadByOthers() {
      for (auto& d : *detectors) d->SetReadByOthers(nullptr);
    }
  };

  // `run` on the detectors of the families `which`, each family on whichever worker takes it
  // next (one detector is never used by two threads at once): (*found)[i] and (*skipped)[i]
  // for each i of `which`; the first family's error (in `which` order) rethrown after all ran.
  template <typename Run>
  void EachOf(const std::vector<size_t>& which, Run run, std::vector<std::vector<MarkerObservation>>* found,
              std::vector<int>* skipped, int threads = 0) {
    if (threads <= 0) threads = options_.threads;
    const size_t n = which.size();
    std::vector<std::exception_ptr> errors(n);
    std::atomic<size_t> next{0};
    const auto work = [&] {
      for (size_t k = next++; k < n; k = next++) {
        const size_t i = which[k];
        try {
          (*found)[i] = run(*detectors_[i]);
          (*skipped)[i] = detectors_[i]->SkippedAttempts();
        } catch (...) {
          errors[k] = std::current_exception();
        }
      }
    };
    std::vector<std::thread> helpers;
    for (size_t t = 1; t < std::min<size_t>(threads, n); ++t) helpers.emplace_back(work);
    work();
    for (std::thread& t : helpers) t.join();
    for (const std::exception_ptr& error : errors) {
      if (error) std::rethrow_exception(error);
    }
  }

  // The families' results merged in the families' order, so that the output does not depend
  // on the thread count or on which thread finished first.
  std::vector<MarkerObservation> Merge(const std::vector<std::vector<MarkerObservation>>& found,
                                       const std::vector<int>& skipped) {
    std::vector<MarkerObservation> all;
    skipped_ = 0;
    for (size_t i = 0; i < found.size(); ++i) {
      AppendUnique(found[i], &all);
      skipped_ += skipped[i];
    }
    return all;
  }

  // The candidate stages the families share (detect/quads.h, SecondPassRegions), computed
  // into their per-image caches with the parameters the families ask for. An error is left
  // for the family that asks next (it computes the stage again and throws).
  void WarmSharedStages(const cv::Mat& gray) const {
    try {
      const PixelHashScope hash_once(gray);
      const std::vector<std::string> families = Families();
      const auto has = [&families](const std::string& f) {
        return std::find(families.begin(), families.end(), f) != families.end();
      };
      FindDarkQuads(gray, options_.min_side_px);
      if (has(kFamilyDataMatrix)) FindCoarseDarkQuads(gray, options_.min_side_px);
      if (options_.second_pass && (has(kFamilyQr) || has(kFamilyDataMatrix))) {
        SecondPassRegions(gray, options_.max_candidates, options_.close_up);
      }
    } catch (...) {
    }
  }

  // `run` on every family's detector at once (EachOf over all of them), merged.
  template <typename Run>
  std::vector<MarkerObservation> EachFamily(Run run) {
    const size_t n = detectors_.size();
    std::vector<size_t> all(n);
    for (size_t i = 0; i < n; ++i) all[i] = i;
    std::vector<std::vector<MarkerObservation>> found(n);
    std::vector<int> skipped(n, 0);
    EachOf(all, run, &found, &skipped);
    return Merge(found, skipped);
  }

  std::vector<std::unique_ptr<MarkerDetector>> detectors_;
  DetectorOptions options_;  // options_.threads: the workers of one call
  cv::Mat staged_gray_;
  int skipped_ = 0;
};

}  // namespace

std::unique_ptr<MarkerDetector> CreateDetector(const std::string& family, const DetectorOptions& options) {
  CheckOptions(options);
  if (family == kFamilyQr) return CreateQrDetector(options);
  if (family == kFamilyDataMatrix) return CreateDataMatrixDetector(options);
  const std::vector<std::string> supported = SupportedFamilies();
  if (std::find(supported.begin(), supported.end(), family) != supported.end()) {
    return CreateAprilTagDetector(family, options);
  }
  std::ostringstream message;
  message << "unknown marker family '" << family << "' (supported:";
  for (const std::string& f : supported) message << " " << f;
  message << ")";
  throw std::invalid_argument(message.str());
}

std::unique_ptr<MarkerDetector> CreateMultiDetector(const std::vector<std::string>& families,
                                                    const DetectorOptions& options) {
  if (families.empty()) throw std::invalid_argument("no marker family given");
  std::set<std::string> seen;
  std::vector<std::unique_ptr<MarkerDetector>> detectors;
  for (const std::string& family : families) {
    if (!seen.insert(family).second)
      throw std::invalid_argument("marker family '" + family + "' given twice");
    detectors.push_back(CreateDetector(family, options));
  }
  return std::make_unique<MultiDetector>(std::move(detectors), options);
}

std::vector<std::string> ParseFamilyList(const std::string& comma_separated) {
  std::vector<std::string> families;
  std::stringstream stream(comma_separated);
  std::string item;
  const std::vector<std::string> supported = SupportedFamilies();
  while (std::getline(stream, item, ',')) {
    if (item.empty()) throw std::invalid_argument("empty marker family in '" + comma_separated + "'");
    if (std::find(supported.begin(), supported.end(), item) == supported.end()) {
      throw std::invalid_argument("unknown marker family '" + item + "' in '" + comma_separated + "'");
    }
    families.push_back(item);
  }
  if (families.empty() || comma_separated.back() == ',') {
    throw std::invalid_argument("empty marker family in '" + comma_separated + "'");
  }
  return families;
}

}  // namespace waymark
