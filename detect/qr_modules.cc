#include "detect/qr_modules.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "detect/module_fit.h"
#include "detect/qr_grid.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

// Grid fit: corner steps (fractions of a module), rounds per step.
constexpr double kGridSteps[] = {0.4, 0.2, 0.1};
constexpr int kGridRounds = 2;
// Module sample: the centre and four points at a quarter module, weighted.
constexpr double kCentreWeight = 0.4, kSideWeight = 0.15, kSampleOffset = 0.25;
// Deconvolution: coordinate-descent sweeps, ICM sweeps.
constexpr int kDescentSweeps = 30;
constexpr int kIcmSweeps = 10;
// Blur model: at least this many known modules with known neighbourhoods.
constexpr int kMinModelModules = 40;
// Soft decisions: the least certain modules flipped one at a time.
constexpr int kSoftFlips = 8;
constexpr int kQuietModules = 4;
// Unoriented quads: module counts tried (versions 1-2), hypotheses fitted (best raw contrast).
constexpr int kMaxUnorientedModules = 25;
constexpr size_t kUnorientedFits = 2;
// Unoriented quads are mostly clutter (recall bench, issue and hard scenarios, seeds 1-3:
// 4 codes read of 2667 quads tried, 3 per frame, each two grid fits and up to 18 decodes):
// none is fitted unless its best hypothesis' known-module contrast (light minus dark, gray
// levels) reaches kMinUnorientedRawContrast (the codes read: 9.6-41.7; clutter: median 2.8,
// 3/4 under 4.8), none decoded unless the best fitted grid's reaches
// kMinUnorientedFitContrast (the codes read: 43.5-70.3; clutter: 9/10 under 19.3). Each
// threshold is about half the weakest code's. Between the two, kMinUnorientedCodeLikeness
// (detect/qr_modules.h) turns away before the fits the quads whose known modules explain
// little of their samples' variation.
constexpr double kMinUnorientedFitContrast = 20.0;
// Perspective search (ReadUnorientedQrModuleGrid, after the fitted grids fail to decode): the
// best grid's corners moved again, in smaller steps (fractions of a module, rounds per step),
// to maximize the known-module contrast plus the spread of the data modules' samples
// (kDataSpreadWeight standard deviations), then decoded once more.
constexpr double kSearchSteps[] = {0.3, 0.15, 0.075};
constexpr int kSearchRounds = 3;
constexpr double kDataSpreadWeight = 2.0;
// Photometric refit (ReadUnorientedQrModuleGrid, after the perspective search fails): rounds
// of (read the modules, fit the whole pattern as read, detect/module_fit.h), each corner free
// to move up to max(px, modules x module) from where the round starts (a quad from a dark
// blob's hull is a module or so off; the fit's own default allows 0.4 module).
constexpr int kPhotometricRounds = 2;
constexpr double kPhotometricMaxShiftModules = 1.0;
constexpr double kPhotometricMaxShiftPx = 1.5;

// The blur model's neighbourhood: offsets (dr, dc) and their weight class (0 the module
// itself, 1 edge neighbours, 2 diagonal, 3 two modules along an axis).
struct Offset {
  int dr, dc, cls;
};
constexpr Offset kNeighbourhood[] = {{0, 0, 0},   {-1, 0, 1}, {1, 0, 1},  {0, -1, 1}, {0, 1, 1},
                                     {-1, -1, 2}, {-1, 1, 2}, {1, -1, 2}, {1, 1, 2},  {-2, 0, 3},
                                     {2, 0, 3},   {0, -2, 3}, {0, 2, 3}};

// Known function-pattern modules of an n-module symbol (versions 1-6): -1 unknown, 0 light,
// 1 dark; row-major.
std::vector<int8_t> KnownModules(int n) {
  std::vector<int8_t> known(static_cast<size_t>(n * n), -1);
  const auto set = [&](int r, int c, int value) {
    if (r >= 0 && c >= 0 && r < n && c < n)
      known[static_cast<size_t>(r * n + c)] = static_cast<int8_t>(value);
  };
  // Finders with their separators: 8x8 blocks at three corners.
  for (const auto& [r0, c0] : {std::pair<int, int>{0, 0}, {0, n - 7}, {n - 7, 0}}) {
    for (int i = -1; i <= 7; ++i) {
      for (int j = -1; j <= 7; ++j) {
        const int ring = std::max(std::abs(i - 3), std::abs(j - 3));
        set(r0 + i, c0 + j, ring <= 3 && ring != 2 ? 1 : 0);
      }
    }
  }
  for (int k = 8; k <= n - 9; ++k) {
    set(6, k, k % 2 == 0 ? 1 : 0);
    set(k, 6, k % 2 == 0 ? 1 : 0);
  }
  set(n - 8, 8, 1);  // the dark module
  if (n >= 25) {
    const int centre = n - 7;
    for (int i = -2; i <= 2; ++i) {
      for (int j = -2; j <= 2; ++j)
        set(centre + i, centre + j, std::max(std::abs(i), std::abs(j)) == 1 ? 0 : 1);
    }
  }
  return known;
}

// Bilinear gray level at image point (x, y); false outside the image.
bool Bilinear(const cv::Mat& gray, double x, double y, double* value) {
  if (!(x >= 0.0 && y >= 0.0 && x <= gray.cols - 1.0 && y <= gray.rows - 1.0)) return false;
  const int x0 = std::min(static_cast<int>(x), gray.cols - 2),
            y0 = std::min(static_cast<int>(y), gray.rows - 2);
  const double fx = x - x0, fy = y - y0;
  const uint8_t* r0 = gray.ptr<uint8_t>(y0);
  const uint8_t* r1 = gray.ptr<uint8_t>(y0 + 1);
  *value = (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
  return true;
}

// The weighted sample of module (r, c); false if a point leaves the image.
bool ModuleSample(const cv::Mat& gray, const cv::Matx33d& H, int r, int c, double* value) {
  static constexpr double kDu[] = {0.0, -kSampleOffset, kSampleOffset, 0.0, 0.0};
  static constexpr double kDv[] = {0.0, 0.0, 0.0, -kSampleOffset, kSampleOffset};
  double sum = 0.0;
  for (int s = 0; s < 5; ++s) {
    const double u = c + 0.5 + kDu[s], v = r + 0.5 + kDv[s];
    const double w = H(2, 0) * u + H(2, 1) * v + H(2, 2);
    double g = 0.0;
    if (!(w > 0.0) || !Bilinear(gray, (H(0, 0) * u + H(0, 1) * v + H(0, 2)) / w,
                                (H(1, 0) * u + H(1, 1) * v + H(1, 2)) / w, &g)) {
      return false;
    }
    sum += (s == 0 ? kCentreWeight : kSideWeight) * g;
  }
  *value = sum;
  return true;
}

// Every module's sample (row-major); false if one leaves the image.
bool SampleModules(const cv::Mat& gray, const Quad2d& corners_px, int n, std::vector<double>* y) {
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  y->assign(static_cast<size_t>(n * n), 0.0);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (!ModuleSample(gray, H, r, c, &(*y)[static_cast<size_t>(r * n + c)])) return false;
    }
  }
  return true;
}

// Mean known-light minus mean known-dark sample; NaN if a sample leaves the image.
double KnownContrast(const cv::Mat& gray, const Quad2d& corners_px, int n, const std::vector<int8_t>& known) {
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  double light = 0.0, dark = 0.0;
  int light_count = 0, dark_count = 0;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const int8_t k = known[static_cast<size_t>(r * n + c)];
      if (k < 0) continue;
      double g = 0.0;
      if (!ModuleSample(gray, H, r, c, &g)) return NAN;
      (k ? dark : light) += g;
      ++(k ? dark_count : light_count);
    }
  }
  return light / light_count - dark / dark_count;
}

// Known-module contrast (mean light minus mean dark sample) and the standard deviation of the
// unknown (data) modules' samples; false if a sample leaves the image.
bool KnownContrastAndDataSpread(const cv::Mat& gray, const Quad2d& corners_px, int n,
                                const std::vector<int8_t>& known, double* contrast, double* spread) {
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  double light = 0.0, dark = 0.0, sum = 0.0, sum_sq = 0.0;
  int light_count = 0, dark_count = 0, data_count = 0;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const int8_t k = known[static_cast<size_t>(r * n + c)];
      double g = 0.0;
      if (!ModuleSample(gray, H, r, c, &g)) return false;
      if (k < 0) {
        sum += g;
        sum_sq += g * g;
        ++data_count;
      } else {
        (k ? dark : light) += g;
        ++(k ? dark_count : light_count);
      }
    }
  }
  const double mean = sum / data_count;
  *contrast = light / light_count - dark / dark_count;
  *spread = std::sqrt(std::max(0.0, sum_sq / data_count - mean * mean));
  return true;
}

// Known-module contrast over the data modules' spread (UnorientedCodeLikeness); NaN if a
// sample leaves the image, +infinity for a positive contrast over data samples that do not vary.
double KnownContrastToDataSpread(const cv::Mat& gray, const Quad2d& corners_px, int n,
                                 const std::vector<int8_t>& known) {
  double contrast = 0.0, spread = 0.0;
  if (!KnownContrastAndDataSpread(gray, corners_px, n, known, &contrast, &spread)) return NAN;
  if (!(spread > 0.0)) return contrast > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
  return contrast / spread;
}

// Known-module contrast plus kDataSpreadWeight standard deviations of the unknown modules'
// samples: on a blurred code the data modules' samples spread most when taken at the module
// centres, and the data area (half the symbol, most of it away from the finders) pins the
// perspective that the known modules, three blocks at three corners, leave loose. NaN if a
// sample leaves the image.
double GridSharpness(const cv::Mat& gray, const Quad2d& corners_px, int n, const std::vector<int8_t>& known) {
  double contrast = 0.0, spread = 0.0;
  if (!KnownContrastAndDataSpread(gray, corners_px, n, known, &contrast, &spread)) return NAN;
  return contrast + kDataSpreadWeight * spread;
}

// Darkness of module (r, c) in the current estimate; outside the symbol: light.
double DarkAt(const std::vector<double>& d, int n, int r, int c) {
  return r < 0 || c < 0 || r >= n || c >= n ? 0.0 : d[static_cast<size_t>(r * n + c)];
}

struct BlurModel {
  // y = a + a_u u + a_v v + sum over the neighbourhood of weight[cls] * d.
  double a = 0.0, a_u = 0.0, a_v = 0.0;
  std::array<double, 4> weight = {0.0, 0.0, 0.0, 0.0};
  double Base(int r, int c, int n) const {
    return a + a_u * ((c + 0.5) / n - 0.5) + a_v * ((r + 0.5) / n - 0.5);
  }
};

std::optional<BlurModel> FitBlurModel(const std::vector<double>& y, const std::vector<int8_t>& known, int n) {
  std::vector<std::array<double, 7>> rows;
  std::vector<double> values;
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (known[static_cast<size_t>(r * n + c)] < 0) continue;
      std::array<double, 7> f = {1.0, (c + 0.5) / n - 0.5, (r + 0.5) / n - 0.5, 0.0, 0.0, 0.0, 0.0};
      bool all_known = true;
      for (const Offset& o : kNeighbourhood) {
        const int rr = r + o.dr, cc = c + o.dc;
        if (rr < 0 || cc < 0 || rr >= n || cc >= n) continue;  // light quiet zone
        const int8_t k = known[static_cast<size_t>(rr * n + cc)];
        if (k < 0) {
          all_known = false;
          break;
        }
        f[3 + o.cls] += k;
      }
      if (!all_known) continue;
      rows.push_back(f);
      values.push_back(y[static_cast<size_t>(r * n + c)]);
    }
  }
  if (static_cast<int>(rows.size()) < kMinModelModules) return std::nullopt;
  Eigen::MatrixXd A(rows.size(), 7);
  Eigen::VectorXd b(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    for (int j = 0; j < 7; ++j) A(static_cast<Eigen::Index>(i), j) = rows[i][static_cast<size_t>(j)];
    b(static_cast<Eigen::Index>(i)) = values[i];
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  if (!x.allFinite() || !(x(3) < 0.0)) return std::nullopt;
  BlurModel model;
  model.a = x(0), model.a_u = x(1), model.a_v = x(2);
  for (int j = 0; j < 4; ++j) model.weight[static_cast<size_t>(j)] = x(3 + j);
  return model;
}

// Residuals y - prediction of every module.
std::vector<double> Residuals(const std::vector<double>& y, const std::vector<double>& d, const BlurModel& m,
                              int n) {
  std::vector<double> residual(y.size());
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      double p = m.Base(r, c, n);
      for (const Offset& o : kNeighbourhood)
        p += m.weight[static_cast<size_t>(o.cls)] * DarkAt(d, n, r + o.dr, c + o.dc);
      residual[static_cast<size_t>(r * n + c)] = y[static_cast<size_t>(r * n + c)] - p;
    }
  }
  return residual;
}

// Change of the squared residual if module (r, c) changes by `delta`, and the
// least-squares step for it (sum w r / sum w^2).
void ModuleEffect(const std::vector<double>& residual, const BlurModel& m, int n, int r, int c, double delta,
                  double* energy_change, double* step) {
  double num = 0.0, den = 0.0, change = 0.0;
  for (const Offset& o : kNeighbourhood) {
    const int rr = r - o.dr, cc = c - o.dc;  // observations that see (r, c)
    if (rr < 0 || cc < 0 || rr >= n || cc >= n) continue;
    const double w = m.weight[static_cast<size_t>(o.cls)];
    const double res = residual[static_cast<size_t>(rr * n + cc)];
    num += w * res;
    den += w * w;
    const double after = res - w * delta;
    change += after * after - res * res;
  }
  if (energy_change) *energy_change = change;
  if (step) *step = den > 0.0 ? num / den : 0.0;
}

void ApplyChange(std::vector<double>* residual, const BlurModel& m, int n, int r, int c, double delta) {
  for (const Offset& o : kNeighbourhood) {
    const int rr = r - o.dr, cc = c - o.dc;
    if (rr < 0 || cc < 0 || rr >= n || cc >= n) continue;
    (*residual)[static_cast<size_t>(rr * n + cc)] -= m.weight[static_cast<size_t>(o.cls)] * delta;
  }
}

struct Deconvolved {
  std::vector<double> soft;        // d in [0, 1]
  std::vector<uint8_t> binary;     // after ICM
  std::vector<int> least_certain;  // unknown modules, smallest |energy change| of a flip first
};

std::optional<Deconvolved> Deconvolve(const cv::Mat& gray, const QrModuleGrid& grid) {
  const int n = grid.modules;
  const std::vector<int8_t> known = KnownModules(n);
  std::vector<double> y;
  if (!SampleModules(gray, grid.corners_px, n, &y)) return std::nullopt;
  const std::optional<BlurModel> model = FitBlurModel(y, known, n);
  if (!model) return std::nullopt;
  Deconvolved out;
  out.soft.assign(y.size(), 0.5);
  for (size_t i = 0; i < y.size(); ++i) {
    if (known[i] >= 0) out.soft[i] = known[i];
  }
  std::vector<double> residual = Residuals(y, out.soft, *model, n);
  for (int sweep = 0; sweep < kDescentSweeps; ++sweep) {
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        const size_t i = static_cast<size_t>(r * n + c);
        if (known[i] >= 0) continue;
        double step = 0.0;
        ModuleEffect(residual, *model, n, r, c, 0.0, nullptr, &step);
        const double updated = std::clamp(out.soft[i] + step, 0.0, 1.0);
        ApplyChange(&residual, *model, n, r, c, updated - out.soft[i]);
        out.soft[i] = updated;
      }
    }
  }
  // Binary by iterated conditional modes from the thresholded soft values.
  std::vector<double> hard(out.soft.size());
  for (size_t i = 0; i < hard.size(); ++i) hard[i] = out.soft[i] >= 0.5 ? 1.0 : 0.0;
  residual = Residuals(y, hard, *model, n);
  std::vector<double> flip_cost(hard.size(), 0.0);
  for (int sweep = 0; sweep < kIcmSweeps; ++sweep) {
    bool changed = false;
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        const size_t i = static_cast<size_t>(r * n + c);
        if (known[i] >= 0) continue;
        const double delta = 1.0 - 2.0 * hard[i];
        double change = 0.0;
        ModuleEffect(residual, *model, n, r, c, delta, &change, nullptr);
        if (change < 0.0) {
          ApplyChange(&residual, *model, n, r, c, delta);
          hard[i] += delta;
          changed = true;
          change = -change;
        }
        flip_cost[i] = change;
      }
    }
    if (!changed) break;
  }
  out.binary.resize(hard.size());
  for (size_t i = 0; i < hard.size(); ++i) {
    out.binary[i] = static_cast<uint8_t>(hard[i] > 0.5);
    if (known[i] < 0) out.least_certain.push_back(static_cast<int>(i));
  }
  std::stable_sort(out.least_certain.begin(), out.least_certain.end(), [&](int a, int b) {
    return flip_cost[static_cast<size_t>(a)] < flip_cost[static_cast<size_t>(b)];
  });
  return out;
}

// Coordinate ascent of a quad's corners on `score` (higher is better; a non-finite value is
// never taken): for each step (in modules of module_px) at most `rounds` rounds, each moving
// every corner along x and y by one step where that scores higher (the first such move per
// corner and axis), until a round moves nothing. *corners and *best are updated in place.
template <typename Steps, typename Score>
void ClimbCorners(double module_px, const Steps& steps, int rounds, const Score& score, Quad2d* corners,
                  double* best) {
  for (const double step_modules : steps) {
    const double step = step_modules * module_px;
    for (int round = 0; round < rounds; ++round) {
      bool moved = false;
      for (int corner = 0; corner < 4; ++corner) {
        for (int axis = 0; axis < 2; ++axis) {
          for (const double sign : {1.0, -1.0}) {
            Quad2d trial = *corners;
            trial[static_cast<size_t>(corner)][axis] += sign * step;
            const double value = score(trial);
            if (std::isfinite(value) && value > *best) {
              *corners = trial;
              *best = value;
              moved = true;
              break;
            }
          }
        }
      }
      if (!moved) break;
    }
  }
}

// zxing on the rendered matrix; corners mapped back through the grid.
std::vector<MarkerObservation> DecodeMatrix(const std::vector<uint8_t>& dark, const QrModuleGrid& grid) {
  const int n = grid.modules;
  ZxingPass pass;
  pass.pure = true;
  pass.try_harder = false;
  std::vector<MarkerObservation> read =
      ReadWithZxing(RenderQrModules(dark, n), ZxingSymbology::kQrCode, pass);
  if (read.size() != 1) return {};
  // The render is upright: the symbol's corners are the grid's (zxing's pure reader places
  // its corners a pixel or so off on the render).
  read[0].corners_px = grid.corners_px;
  return read;
}

}  // namespace

std::optional<QrModuleGrid> FitQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int modules) {
  if (gray.empty() || gray.type() != CV_8UC1 || modules < kMinGridModules || modules > kMaxGridModules ||
      (modules - 17) % 4 != 0) {
    return std::nullopt;
  }
  const std::vector<int8_t> known = KnownModules(modules);
  QrModuleGrid grid;
  grid.modules = modules;
  grid.corners_px = corners_px;
  grid.contrast = KnownContrast(gray, corners_px, modules, known);
  if (!std::isfinite(grid.contrast)) return std::nullopt;
  ClimbCorners(
      QuadMeanSide(corners_px) / modules, kGridSteps, kGridRounds,
      [&](const Quad2d& trial) { return KnownContrast(gray, trial, modules, known); }, &grid.corners_px,
      &grid.contrast);
  if (!(grid.contrast > 0.0)) return std::nullopt;
  return grid;
}

std::optional<std::vector<double>> DeconvolveQrModules(const cv::Mat& gray, const QrModuleGrid& grid) {
  if (gray.empty() || gray.type() != CV_8UC1 || grid.modules < kMinGridModules ||
      grid.modules > kMaxGridModules)
    return std::nullopt;
  const std::optional<Deconvolved> result = Deconvolve(gray, grid);
  if (!result) return std::nullopt;
  return result->soft;
}

cv::Mat RenderQrModules(const std::vector<uint8_t>& dark, int modules) {
  const int side = (modules + 2 * kQuietModules) * kRenderModulePx;
  cv::Mat image(side, side, CV_8UC1, cv::Scalar(255));
  for (int r = 0; r < modules; ++r) {
    for (int c = 0; c < modules; ++c) {
      if (!dark[static_cast<size_t>(r * modules + c)]) continue;
      image(cv::Rect((c + kQuietModules) * kRenderModulePx, (r + kQuietModules) * kRenderModulePx,
                     kRenderModulePx, kRenderModulePx))
          .setTo(0);
    }
  }
  return image;
}

namespace {

// The grid's corners moved to maximize GridSharpness (coordinate ascent, kSearchSteps).
QrModuleGrid SearchGridPerspective(const cv::Mat& gray, const QrModuleGrid& start) {
  const int n = start.modules;
  const std::vector<int8_t> known = KnownModules(n);
  QrModuleGrid grid = start;
  double score = GridSharpness(gray, grid.corners_px, n, known);
  if (!std::isfinite(score)) return start;
  ClimbCorners(
      QuadMeanSide(grid.corners_px) / n, kSearchSteps, kSearchRounds,
      [&](const Quad2d& trial) { return GridSharpness(gray, trial, n, known); }, &grid.corners_px, &score);
  grid.contrast = KnownContrast(gray, grid.corners_px, n, known);
  return grid;
}

// The grids decoded in turn (steps 2-4); the first read.
std::vector<MarkerObservation> DecodeGrids(const cv::Mat& gray, const std::vector<QrModuleGrid>& grids) {
  for (const QrModuleGrid& grid : grids) {
    const std::optional<Deconvolved> modules_read = Deconvolve(gray, grid);
    if (!modules_read) continue;
    std::vector<MarkerObservation> read = DecodeMatrix(modules_read->binary, grid);
    for (int k = 0;
         read.empty() && k < kSoftFlips && k < static_cast<int>(modules_read->least_certain.size()); ++k) {
      std::vector<uint8_t> flipped = modules_read->binary;
      const size_t i = static_cast<size_t>(modules_read->least_certain[static_cast<size_t>(k)]);
      flipped[i] = static_cast<uint8_t>(1 - flipped[i]);
      read = DecodeMatrix(flipped, grid);
    }
    if (!read.empty()) return read;
  }
  return {};
}

}  // namespace

std::vector<MarkerObservation> ReadQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int modules) {
  if (gray.empty() || gray.type() != CV_8UC1) return {};
  // The module count estimated from the finders can be a version off: the neighbours too,
  // best known-pattern contrast first.
  std::vector<QrModuleGrid> grids;
  for (const int n : {modules, modules - 4, modules + 4}) {
    if (const std::optional<QrModuleGrid> grid = FitQrModuleGrid(gray, corners_px, n)) grids.push_back(*grid);
  }
  std::stable_sort(grids.begin(), grids.end(),
                   [](const QrModuleGrid& a, const QrModuleGrid& b) { return a.contrast > b.contrast; });
  return DecodeGrids(gray, grids);
}

double UnorientedKnownModuleContrast(const cv::Mat& gray, const Quad2d& corners_px) {
  double best = -std::numeric_limits<double>::infinity();
  if (gray.empty() || gray.type() != CV_8UC1) return best;
  for (int rotation = 0; rotation < 4; ++rotation) {
    const Quad2d corners = RotateCorners(corners_px, rotation);
    for (int n = kMinGridModules; n <= kMaxUnorientedModules; n += 4) {
      const double contrast = KnownContrast(gray, corners, n, KnownModules(n));
      if (std::isfinite(contrast)) best = std::max(best, contrast);
    }
  }
  return best;
}

namespace {

// An unoriented quad's hypotheses (rotation, module count) by known-module contrast, best first.
struct Hypothesis {
  Quad2d corners;
  int modules;
  double contrast;
};
std::vector<Hypothesis> RankedHypotheses(const cv::Mat& gray, const Quad2d& corners_px) {
  std::vector<Hypothesis> hypotheses;
  for (int rotation = 0; rotation < 4; ++rotation) {
    const Quad2d corners = RotateCorners(corners_px, rotation);
    for (int n = kMinGridModules; n <= kMaxUnorientedModules; n += 4) {
      const double contrast = KnownContrast(gray, corners, n, KnownModules(n));
      if (std::isfinite(contrast)) hypotheses.push_back({corners, n, contrast});
    }
  }
  std::stable_sort(hypotheses.begin(), hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.contrast > b.contrast; });
  return hypotheses;
}

// UnorientedCodeLikeness of the hypotheses that would be fitted (the first kUnorientedFits).
double BestCodeLikeness(const cv::Mat& gray, const std::vector<Hypothesis>& hypotheses) {
  double best = -std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < hypotheses.size() && k < kUnorientedFits; ++k) {
    const double ratio = KnownContrastToDataSpread(gray, hypotheses[k].corners, hypotheses[k].modules,
                                                   KnownModules(hypotheses[k].modules));
    if (!std::isnan(ratio)) best = std::max(best, ratio);
  }
  return best;
}

}  // namespace

double UnorientedCodeLikeness(const cv::Mat& gray, const Quad2d& corners_px) {
  if (gray.empty() || gray.type() != CV_8UC1) return -std::numeric_limits<double>::infinity();
  return BestCodeLikeness(gray, RankedHypotheses(gray, corners_px));
}

double UnorientedCodeEvidence(const cv::Mat& gray, const Quad2d& corners_px) {
  if (gray.empty() || gray.type() != CV_8UC1) return 0.0;
  const std::vector<Hypothesis> hypotheses = RankedHypotheses(gray, corners_px);
  if (hypotheses.empty()) return 0.0;
  const double likeness = BestCodeLikeness(gray, hypotheses), contrast = hypotheses[0].contrast;
  return likeness > 0.0 && contrast > 0.0 ? likeness * contrast : 0.0;
}

std::vector<MarkerObservation> ReadUnorientedQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px) {
  if (gray.empty() || gray.type() != CV_8UC1) return {};
  const std::vector<Hypothesis> hypotheses = RankedHypotheses(gray, corners_px);
  if (hypotheses.empty() || !(hypotheses[0].contrast >= kMinUnorientedRawContrast)) return {};
  // Clutter whose known modules explain little of its variation, or whose contrast times that
  // likeness (UnorientedCodeEvidence) is under kMinUnorientedFitEvidence: no fit.
  const double likeness = BestCodeLikeness(gray, hypotheses);
  if (!(likeness >= kMinUnorientedCodeLikeness) ||
      !(likeness * hypotheses[0].contrast >= kMinUnorientedFitEvidence)) {
    return {};
  }
  std::vector<QrModuleGrid> grids;
  for (size_t k = 0; k < hypotheses.size() && k < kUnorientedFits; ++k) {
    if (const std::optional<QrModuleGrid> grid =
            FitQrModuleGrid(gray, hypotheses[k].corners, hypotheses[k].modules))
      grids.push_back(*grid);
  }
  std::stable_sort(grids.begin(), grids.end(),
                   [](const QrModuleGrid& a, const QrModuleGrid& b) { return a.contrast > b.contrast; });
  if (grids.empty() || !(grids[0].contrast >= kMinUnorientedFitContrast)) return {};
  std::vector<MarkerObservation> read = DecodeGrids(gray, grids);
  if (!read.empty()) return read;
  // The finder-less corner is held by few known modules: the perspective search, once.
  QrModuleGrid grid = SearchGridPerspective(gray, grids[0]);
  read = DecodeGrids(gray, {grid});
  // Then the whole pattern as read, wrong modules and all, fitted photometrically (the blur
  // through the homography, detect/module_fit.h): every module edge pulls on the corners, not
  // only the known modules'; the grid is read again at the fitted corners.
  for (int round = 0; read.empty() && round < kPhotometricRounds; ++round) {
    const std::optional<Deconvolved> modules_read = Deconvolve(gray, grid);
    if (!modules_read) break;
    ModuleFitOptions options;
    options.max_shift_modules = kPhotometricMaxShiftModules;
    options.max_shift_px = kPhotometricMaxShiftPx;
    const std::optional<ModuleFit> fit =
        FitModuleGrid(gray, grid.corners_px, grid.modules, modules_read->binary, options);
    if (!fit) break;
    grid.corners_px = fit->corners_px;
    read = DecodeGrids(gray, {grid});
  }
  return read;
}

}  // namespace waymark
