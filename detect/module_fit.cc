#include "detect/module_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace waymark {
namespace {

constexpr int kGeometry = 8;            // entries of G (G(2, 2) = 1)
constexpr int kParams = kGeometry + 1;  // and sigma
constexpr int kLinear = 4;              // a, b, c, d
constexpr double kMinBlurPx = 0.15;
constexpr double kMaxBlurPx = 4.0;
constexpr double kStartBlurPx = 0.8;
constexpr double kBlurReach = 3.0;      // modules within this many sigmas of a pixel enter its sum
constexpr double kConvergedPx = 0.003;  // the last step's largest corner move
constexpr double kHuber = 1.345;        // Huber threshold, robust sigmas
constexpr double kInvSqrt2 = 0.70710678118654752440;
constexpr double kInvSqrt2Pi = 0.39894228040143267794;

// The standard normal CDF and density, tabulated on [-kTableReach, kTableReach] every
// 1 / kTableSteps and interpolated linearly (errors under 2e-6): the fit evaluates them a few
// ten thousand times per iteration.
constexpr double kTableReach = 8.0;
constexpr int kTableSteps = 128;
constexpr int kTableSize = static_cast<int>(2 * kTableReach * kTableSteps) + 1;

struct NormalTable {
  std::array<double, kTableSize> cdf{}, pdf{};
  NormalTable() {
    for (int k = 0; k < kTableSize; ++k) {
      const double t = -kTableReach + static_cast<double>(k) / kTableSteps;
      cdf[k] = 0.5 * std::erfc(-t * kInvSqrt2);
      pdf[k] = kInvSqrt2Pi * std::exp(-0.5 * t * t);
    }
  }
};

const NormalTable& Table() {
  static const NormalTable table;
  return table;
}

// Phi(t) and phi(t) from the table.
inline void Normal(const NormalTable& table, double t, double* cdf, double* pdf) {
  const double x = (t + kTableReach) * kTableSteps;
  if (!(x > 0.0)) {
    *cdf = 0.0;
    *pdf = 0.0;
    return;
  }
  if (x >= kTableSize - 1) {
    *cdf = 1.0;
    *pdf = 0.0;
    return;
  }
  const int k = static_cast<int>(x);
  const double f = x - k;
  *cdf = table.cdf[k] + f * (table.cdf[k + 1] - table.cdf[k]);
  *pdf = table.pdf[k] + f * (table.pdf[k + 1] - table.pdf[k]);
}

// A hash of a pixel's position.
inline uint32_t PositionHash(int r, int c) {
  uint32_t h = static_cast<uint32_t>(r) * 0x9E3779B1u ^ static_cast<uint32_t>(c) * 0x85EBCA77u;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  return h;
}

struct Pixel {
  double x = 0.0, y = 0.0;  // normalized image coordinates
  double value = 0.0;       // gray level
};

// The model's prediction B and its derivatives at one pixel.
struct Prediction {
  double b = 0.0;  // blurred darkness, 0 (light) .. 1 (dark)
  double du = 0.0, dv = 0.0, dsigma = 0.0;
  double u = 0.0, v = 0.0, w = 1.0;
};

class GridModel {
 public:
  GridModel(int n, const std::vector<uint8_t>& dark, double scale_px)
      : n_(n),
        stride_(n + 2 * kPad),
        padded_(static_cast<size_t>(stride_) * stride_, 0),
        scale_px_(scale_px) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) padded_[(j + kPad) * stride_ + i + kPad] = dark[j * n + i] != 0 ? 1 : 0;
    }
  }

  // Module (i, j) is dark; modules outside the symbol are light.
  bool Dark(int i, int j) const {
    if (i < -kPad || j < -kPad || i >= n_ + kPad || j >= n_ + kPad) return false;
    return padded_[(j + kPad) * stride_ + i + kPad] != 0;
  }

  // B at pixel p for G = g (8 entries) and blur sigma_px.
  Prediction Predict(const Pixel& p, const double* g, double sigma_px) const {
    Prediction out;
    const double w0 = g[0] * p.x + g[1] * p.y + g[2];
    const double w1 = g[3] * p.x + g[4] * p.y + g[5];
    const double w2 = g[6] * p.x + g[7] * p.y + 1.0;
    out.w = w2;
    out.u = w0 / w2;
    out.v = w1 / w2;
    // Module coordinates per image pixel along x and y (the local Jacobian of G).
    const double inv_sw = 1.0 / (w2 * scale_px_);
    const double ux = (g[0] - out.u * g[6]) * inv_sw, uy = (g[1] - out.u * g[7]) * inv_sw;
    const double vx = (g[3] - out.v * g[6]) * inv_sw, vy = (g[4] - out.v * g[7]) * inv_sw;
    const double ku = std::sqrt(ux * ux + uy * uy), kv = std::sqrt(vx * vx + vy * vy);
    const double su = sigma_px * ku, sv = sigma_px * kv;
    // A trial step can put the horizon (w2 = 0) near the symbol: such a pixel predicts light
    // (its cost then rejects the step); far outside the symbol every module is light anyway.
    constexpr double kFarModules = 1e4;
    if (!(std::abs(out.u) < kFarModules && std::abs(out.v) < kFarModules && su > 1e-9 && sv > 1e-9 &&
          su < kFarModules && sv < kFarModules)) {
      out.du = out.dv = out.dsigma = 0.0;
      return out;
    }
    const int i0 = static_cast<int>(std::floor(out.u - kBlurReach * su));
    const int i1 = static_cast<int>(std::floor(out.u + kBlurReach * su));
    const int j0 = static_cast<int>(std::floor(out.v - kBlurReach * sv));
    const int j1 = static_cast<int>(std::floor(out.v + kBlurReach * sv));
    // A window wider than this is no small symbol's pixel (the caller bounds the blur).
    constexpr int kMaxSpan = 16;
    if (i1 - i0 >= kMaxSpan || j1 - j0 >= kMaxSpan) return out;
    bool any_dark = false, any_light = false;
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) (Dark(i, j) ? any_dark : any_light) = true;
    }
    if (!any_light) {
      out.b = 1.0;
      return out;
    }
    if (!any_dark) return out;
    // (Left uninitialized: Shares writes the entries used.)
    std::array<double, kMaxSpan> a, da, sa, c, dc, sc;
    Shares(out.u, su, i0, i1, a.data(), da.data(), sa.data());
    Shares(out.v, sv, j0, j1, c.data(), dc.data(), sc.data());
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        if (!Dark(i, j)) continue;
        const int ii = i - i0, jj = j - j0;
        out.b += a[ii] * c[jj];
        out.du += da[ii] * c[jj];
        out.dv += a[ii] * dc[jj];
        out.dsigma += sa[ii] * c[jj] * ku + a[ii] * sc[jj] * kv;
      }
    }
    return out;
  }

 private:
  // Shares of N(x, s^2) in the modules i0 .. i1 ([i, i + 1)), with their derivatives by x
  // and by s.
  static void Shares(double x, double s, int i0, int i1, double* share, double* d_x, double* d_s) {
    const NormalTable& table = Table();
    double cdf_lo = 0.0, pdf_lo = 0.0, t_lo = 0.0;
    for (int e = i0; e <= i1 + 1; ++e) {
      const double t = (e - x) / s;
      double cdf, pdf;
      Normal(table, t, &cdf, &pdf);
      if (e > i0) {
        const int k = e - 1 - i0;
        share[k] = cdf - cdf_lo;
        d_x[k] = -(pdf - pdf_lo) / s;
        d_s[k] = -(pdf * t - pdf_lo * t_lo) / s;
      }
      cdf_lo = cdf;
      pdf_lo = pdf;
      t_lo = t;
    }
  }

  static constexpr int kPad = 16;  // light modules kept around the symbol
  int n_;
  int stride_;
  std::vector<uint8_t> padded_;
  double scale_px_;
};

struct Evaluation {
  double cost = 0.0;  // Huber cost
  double sq_sum = 0.0;
  Eigen::Matrix<double, kLinear, 1> linear = Eigen::Matrix<double, kLinear, 1>::Zero();
  bool ok = false;
};

double HuberWeight(double r, double k) { return std::abs(r) <= k ? 1.0 : k / std::abs(r); }
double HuberCost(double r, double k) { return std::abs(r) <= k ? 0.5 * r * r : k * (std::abs(r) - 0.5 * k); }

// Every pixel's prediction for geometry g and blur sigma.
void PredictAll(const GridModel& model, const std::vector<Pixel>& pixels, const double* g, double sigma,
                std::vector<Prediction>* predictions) {
  predictions->resize(pixels.size());
  for (size_t k = 0; k < pixels.size(); ++k) (*predictions)[k] = model.Predict(pixels[k], g, sigma);
}

// The photometry (a, b, c, d) solved by weighted least squares for the predictions (weights
// `weights`, or 1), and the Huber cost of the residuals.
Evaluation Solve(const std::vector<Pixel>& pixels, const std::vector<Prediction>& predictions, double huber_k,
                 const std::vector<double>* weights) {
  Evaluation out;
  Eigen::Matrix<double, kLinear, kLinear> A = Eigen::Matrix<double, kLinear, kLinear>::Zero();
  Eigen::Matrix<double, kLinear, 1> rhs = Eigen::Matrix<double, kLinear, 1>::Zero();
  for (size_t k = 0; k < pixels.size(); ++k) {
    const Eigen::Matrix<double, kLinear, 1> row(1.0, predictions[k].b, pixels[k].x, pixels[k].y);
    const double w = weights != nullptr ? (*weights)[k] : 1.0;
    // The lower triangle of (w row) row^T, the only part the LDLT below reads.
    const Eigen::Matrix<double, kLinear, 1> w_row = w * row;
    for (int a = 0; a < kLinear; ++a) {
      for (int c = 0; c <= a; ++c) A(a, c) += w_row[a] * row[c];
    }
    rhs += w * pixels[k].value * row;
  }
  for (int a = 0; a < kLinear; ++a) {
    for (int c = 0; c < a; ++c) A(c, a) = A(a, c);
  }
  Eigen::LDLT<Eigen::Matrix<double, kLinear, kLinear>> ldlt(A);
  if (ldlt.info() != Eigen::Success) return out;
  out.linear = ldlt.solve(rhs);
  if (!out.linear.allFinite()) return out;
  for (size_t k = 0; k < pixels.size(); ++k) {
    const double model_value = out.linear[0] + out.linear[1] * predictions[k].b +
                               out.linear[2] * pixels[k].x + out.linear[3] * pixels[k].y;
    const double r = pixels[k].value - model_value;
    out.cost += HuberCost(r, huber_k);
    out.sq_sum += r * r;
  }
  out.ok = true;
  return out;
}

}  // namespace

std::optional<ModuleFit> FitModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int n,
                                       const std::vector<uint8_t>& dark, const ModuleFitOptions& options) {
  if (gray.empty() || gray.type() != CV_8UC1 || n < 1 || dark.size() != static_cast<size_t>(n) * n) {
    return std::nullopt;
  }
  const Eigen::Vector2d centre = QuadCenter(corners_px);
  const double scale_px = QuadMeanSide(corners_px);
  if (!(scale_px > 1.0)) return std::nullopt;
  const double module_px = scale_px / n;
  // G: normalized image -> modules.
  std::vector<cv::Point2f> image, modules;
  const float f = static_cast<float>(n);
  const cv::Point2f module_corners[4] = {{0.f, 0.f}, {f, 0.f}, {f, f}, {0.f, f}};
  for (int k = 0; k < 4; ++k) {
    image.emplace_back(static_cast<float>((corners_px[k].x() - centre.x()) / scale_px),
                       static_cast<float>((corners_px[k].y() - centre.y()) / scale_px));
    modules.push_back(module_corners[k]);
  }
  const cv::Matx33d G0(cv::getPerspectiveTransform(image, modules));
  if (!(std::abs(G0(2, 2)) > 1e-12)) return std::nullopt;
  std::array<double, kParams> params;
  for (int k = 0; k < kGeometry; ++k) params[k] = G0.val[k] / G0(2, 2);
  params[kGeometry] = kStartBlurPx;

  // The pixels whose centres fall in the symbol or its modelled quiet zone at the start.
  std::vector<cv::Point> outline;
  {
    const cv::Matx33d H0 = G0.inv();
    const double q = options.quiet_modules;
    for (const cv::Point2d m :
         {cv::Point2d(-q, -q), cv::Point2d(n + q, -q), cv::Point2d(n + q, n + q), cv::Point2d(-q, n + q)}) {
      const cv::Vec3d p = H0 * cv::Vec3d(m.x, m.y, 1.0);
      if (!(std::abs(p[2]) > 1e-12)) return std::nullopt;
      outline.emplace_back(static_cast<int>(std::lround(p[0] / p[2] * scale_px + centre.x())),
                           static_cast<int>(std::lround(p[1] / p[2] * scale_px + centre.y())));
    }
  }
  const cv::Rect box = cv::boundingRect(outline);
  if (box.x < 0 || box.y < 0 || box.x + box.width > gray.cols || box.y + box.height > gray.rows)
    return std::nullopt;
  if (static_cast<double>(box.area()) > options.max_box_pixels) return std::nullopt;
  const double q = options.quiet_modules;
  const auto inside = [&](int r, int c) {
    const double x = (c - centre.x()) / scale_px, y = (r - centre.y()) / scale_px;
    const double w = params[6] * x + params[7] * y + 1.0;
    const double u = (params[0] * x + params[1] * y + params[2]) / w;
    const double v = (params[3] * x + params[4] * y + params[5]) / w;
    return u >= -q && v >= -q && u <= n + q && v <= n + q;
  };
  int domain = 0;
  for (int r = box.y; r < box.y + box.height; ++r) {
    for (int c = box.x; c < box.x + box.width; ++c) domain += inside(r, c) ? 1 : 0;
  }
  // One pixel in `keep` of the domain, picked by a hash of its position (no lattice that a
  // tilted module grid could alias with).
  const int keep = std::max(1, (domain + options.target_pixels - 1) / options.target_pixels);
  std::vector<Pixel> pixels;
  pixels.reserve(domain / keep + 64);
  for (int r = box.y; r < box.y + box.height; ++r) {
    const uint8_t* row = gray.ptr<uint8_t>(r);
    for (int c = box.x; c < box.x + box.width; ++c) {
      if (keep > 1 && PositionHash(r, c) % keep != 0) continue;
      if (!inside(r, c)) continue;
      pixels.push_back(
          {(c - centre.x()) / scale_px, (r - centre.y()) / scale_px, static_cast<double>(row[c])});
    }
  }
  if (pixels.size() < static_cast<size_t>(4 * n)) {
    return std::nullopt;
  }

  const GridModel model(n, dark, scale_px);
  std::vector<Prediction> predictions;
  // Robust scale: from the unweighted start, the median absolute residual.
  PredictAll(model, pixels, params.data(), params[kGeometry], &predictions);
  Evaluation current = Solve(pixels, predictions, 1e300, nullptr);
  if (!current.ok || !(current.linear[1] < 0.0)) return std::nullopt;
  double huber_k = 0.0;
  {
    std::vector<double> abs_residuals(pixels.size());
    for (size_t k = 0; k < pixels.size(); ++k) {
      abs_residuals[k] = std::abs(pixels[k].value - current.linear[0] - current.linear[1] * predictions[k].b -
                                  current.linear[2] * pixels[k].x - current.linear[3] * pixels[k].y);
    }
    const auto mid = abs_residuals.begin() + abs_residuals.size() / 2;
    std::nth_element(abs_residuals.begin(), mid, abs_residuals.end());
    huber_k = kHuber * std::max(1.0, 1.4826 * *mid);
  }
  const double start_rms = std::sqrt(current.sq_sum / pixels.size());
  current = Solve(pixels, predictions, huber_k, nullptr);
  if (!current.ok) return std::nullopt;

  double lambda = 1e-3;
  int iteration = 0;
  std::vector<double> weights(pixels.size(), 1.0);
  std::vector<Prediction> trial_predictions;
  for (; iteration < options.max_iterations; ++iteration) {
    // Normal equations of the geometry and blur, the photometry held.
    Eigen::Matrix<double, kParams, kParams> JtJ = Eigen::Matrix<double, kParams, kParams>::Zero();
    Eigen::Matrix<double, kParams, 1> Jtr = Eigen::Matrix<double, kParams, 1>::Zero();
    const double b = current.linear[1];
    for (size_t k = 0; k < pixels.size(); ++k) {
      const Prediction& pr = predictions[k];
      const Pixel& p = pixels[k];
      const double r =
          p.value - (current.linear[0] + b * pr.b + current.linear[2] * p.x + current.linear[3] * p.y);
      weights[k] = HuberWeight(r, huber_k);
      if (pr.du == 0.0 && pr.dv == 0.0 && pr.dsigma == 0.0) continue;
      const double inv_w = 1.0 / pr.w;
      Eigen::Matrix<double, kParams, 1> J;
      // d(model)/d(g): b * (dB/du du/dg + dB/dv dv/dg).
      J[0] = b * pr.du * p.x * inv_w;
      J[1] = b * pr.du * p.y * inv_w;
      J[2] = b * pr.du * inv_w;
      J[3] = b * pr.dv * p.x * inv_w;
      J[4] = b * pr.dv * p.y * inv_w;
      J[5] = b * pr.dv * inv_w;
      J[6] = -b * (pr.du * pr.u + pr.dv * pr.v) * p.x * inv_w;
      J[7] = -b * (pr.du * pr.u + pr.dv * pr.v) * p.y * inv_w;
      J[8] = b * pr.dsigma;
      // The lower triangle of (w J) J^T, the only part the LDLT below reads.
      const Eigen::Matrix<double, kParams, 1> wJ = weights[k] * J;
      for (int a = 0; a < kParams; ++a) {
        for (int c = 0; c <= a; ++c) JtJ(a, c) += wJ[a] * J[c];
      }
      Jtr += weights[k] * r * J;
    }
    for (int a = 0; a < kParams; ++a) {
      for (int c = 0; c < a; ++c) JtJ(c, a) = JtJ(a, c);
    }
    const Eigen::Matrix<double, kParams, kParams>& normal = JtJ;
    bool accepted = false;
    double step_px = 0.0;
    for (int attempt = 0; attempt < 8 && !accepted; ++attempt) {
      Eigen::Matrix<double, kParams, kParams> damped = normal;
      damped.diagonal() += lambda * normal.diagonal().cwiseMax(1e-12);
      const Eigen::Matrix<double, kParams, 1> delta = damped.ldlt().solve(Jtr);
      if (!delta.allFinite()) break;
      std::array<double, kParams> trial = params;
      for (int k = 0; k < kParams; ++k) trial[k] += delta[k];
      trial[kGeometry] = std::clamp(trial[kGeometry], kMinBlurPx, kMaxBlurPx);
      PredictAll(model, pixels, trial.data(), trial[kGeometry], &trial_predictions);
      const Evaluation e = Solve(pixels, trial_predictions, huber_k, &weights);
      if (e.ok && e.cost < current.cost) {
        // The step's largest corner move, in pixels.
        const cv::Matx33d before(params[0], params[1], params[2], params[3], params[4], params[5], params[6],
                                 params[7], 1.0);
        const cv::Matx33d after(trial[0], trial[1], trial[2], trial[3], trial[4], trial[5], trial[6],
                                trial[7], 1.0);
        const cv::Matx33d hb = before.inv(), ha = after.inv();
        step_px = 0.0;
        for (const cv::Point2d m : module_corners) {
          const cv::Vec3d pb = hb * cv::Vec3d(m.x, m.y, 1.0), pa = ha * cv::Vec3d(m.x, m.y, 1.0);
          step_px = std::max(
              step_px, scale_px * std::hypot(pa[0] / pa[2] - pb[0] / pb[2], pa[1] / pa[2] - pb[1] / pb[2]));
        }
        params = trial;
        current = e;
        predictions.swap(trial_predictions);
        lambda = std::max(1e-7, lambda / 4.0);
        accepted = true;
      } else {
        lambda *= 8.0;
      }
    }
    if (!accepted || step_px < kConvergedPx) {
      ++iteration;
      break;
    }
  }
  // Unweighted photometry at the result, for the figures reported.
  const Evaluation last = Solve(pixels, predictions, 1e300, nullptr);
  const double blur = params[kGeometry];
  if (!last.ok || !(last.linear[1] < 0.0) || blur <= kMinBlurPx || blur >= kMaxBlurPx) return std::nullopt;
  const cv::Matx33d G(params[0], params[1], params[2], params[3], params[4], params[5], params[6], params[7],
                      1.0);
  const cv::Matx33d H = G.inv();
  ModuleFit fit;
  const double max_move = std::max(options.max_shift_px, options.max_shift_modules * module_px);
  for (int k = 0; k < 4; ++k) {
    const cv::Vec3d p = H * cv::Vec3d(module_corners[k].x, module_corners[k].y, 1.0);
    if (!(std::abs(p[2]) > 1e-12)) return std::nullopt;
    fit.corners_px[k] =
        Eigen::Vector2d(p[0] / p[2] * scale_px + centre.x(), p[1] / p[2] * scale_px + centre.y());
    if (!((fit.corners_px[k] - corners_px[k]).norm() <= max_move)) return std::nullopt;
  }
  fit.blur_px = blur;
  fit.contrast = -last.linear[1];
  fit.residual_rms = std::sqrt(last.sq_sum / pixels.size());
  fit.start_rms = start_rms;
  fit.pixels = static_cast<int>(pixels.size());
  fit.iterations = iteration;
  return fit;
}

}  // namespace waymark
