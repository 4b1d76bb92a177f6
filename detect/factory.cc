// DetectorOptions::Check, the family list and the factories of detect/detector.h.
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

#include "detect/apriltag.h"
#include "detect/common.h"
#include "detect/datamatrix.h"
#include "detect/detector.h"
#include "detect/qr.h"
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
  explicit MultiDetector(std::vector<std::unique_ptr<MarkerDetector>> detectors)
      : detectors_(std::move(detectors)) {}

  std::vector<std::string> Families() const override {
    std::vector<std::string> families;
    for (const auto& d : detectors_) {
      for (const std::string& f : d->Families()) families.push_back(f);
    }
    return families;
  }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const cv::Mat gray = ToGray8(image);  // convert once for every family
    std::vector<MarkerObservation> all;
    skipped_ = 0;
    for (const auto& d : detectors_) {
      AppendUnique(d->Detect(gray), &all);
      skipped_ += d->SkippedAttempts();
    }
    return all;
  }

  int SkippedAttempts() const override { return skipped_; }

 private:
  std::vector<std::unique_ptr<MarkerDetector>> detectors_;
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
  return std::make_unique<MultiDetector>(std::move(detectors));
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
