#include "eval/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "util/format.h"

namespace waymark::eval {
namespace {

constexpr double kWidthPx = 820.0;
constexpr double kLeftPx = 70.0, kRightPx = 20.0;
constexpr double kTopViewTopPx = 50.0, kTopViewHeightPx = 460.0;
constexpr double kErrorTopPx = 570.0, kErrorHeightPx = 200.0;
constexpr size_t kMaxPolylinePoints = 4000;

std::string Num(double value) { return FormatFixed(value, 2); }

std::string Label(double value) { return FormatSignificant(std::abs(value) < 1e-12 ? 0.0 : value, 6); }

std::string Escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

// A "nice" tick step (1, 2 or 5 times a power of ten) for about 6 ticks over `range`.
double TickStep(double range) {
  const double raw = range / 6.0;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0}) {
    if (m * power >= raw) return m * power;
  }
  return 10.0 * power;
}

// Maps a world box to a pixel box: px = x0 + (x - min_x) * scale_x, py = y0 - (y - min_y) * scale_y.
struct Frame {
  double min_x = 0, max_x = 1, min_y = 0, max_y = 1;
  double left_px = 0, top_px = 0, width_px = 1, height_px = 1;
  double PxX(double x) const { return left_px + (x - min_x) / (max_x - min_x) * width_px; }
  double PxY(double y) const { return top_px + height_px - (y - min_y) / (max_y - min_y) * height_px; }
};

struct Bounds {
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x;
  double min_y = min_x, max_y = -min_x;
  void Add(double x, double y) {
    min_x = std::min(min_x, x), max_x = std::max(max_x, x);
    min_y = std::min(min_y, y), max_y = std::max(max_y, y);
  }
  bool Empty() const { return !(min_x <= max_x); }
};

// Equal scales on both axes, 5 % margin, at least 1 m of range.
Frame TopViewFrame(const Bounds& b) {
  const double cx = 0.5 * (b.min_x + b.max_x), cy = 0.5 * (b.min_y + b.max_y);
  const double plot_w = kWidthPx - kLeftPx - kRightPx;
  double half_x = std::max(0.55 * (b.max_x - b.min_x), 0.5),
         half_y = std::max(0.55 * (b.max_y - b.min_y), 0.5);
  // Grow the shorter side so that metres per pixel match on both axes.
  if (half_x / plot_w > half_y / kTopViewHeightPx)
    half_y = half_x / plot_w * kTopViewHeightPx;
  else
    half_x = half_y / kTopViewHeightPx * plot_w;
  return {cx - half_x, cx + half_x,   cy - half_y, cy + half_y,
          kLeftPx,     kTopViewTopPx, plot_w,      kTopViewHeightPx};
}

void DrawAxes(const Frame& f, const std::string& x_title, const std::string& y_title,
              std::ostringstream& svg) {
  svg << "<rect x=\"" << Num(f.left_px) << "\" y=\"" << Num(f.top_px) << "\" width=\"" << Num(f.width_px)
      << "\" height=\"" << Num(f.height_px) << "\" fill=\"white\" stroke=\"#444\"/>\n";
  const double step_x = TickStep(f.max_x - f.min_x), step_y = TickStep(f.max_y - f.min_y);
  for (double x = std::ceil(f.min_x / step_x) * step_x; x <= f.max_x; x += step_x) {
    svg << "<line x1=\"" << Num(f.PxX(x)) << "\" y1=\"" << Num(f.top_px) << "\" x2=\"" << Num(f.PxX(x))
        << "\" y2=\"" << Num(f.top_px + f.height_px) << "\" stroke=\"#e4e4e4\"/>\n<text x=\"" << Num(f.PxX(x))
        << "\" y=\"" << Num(f.top_px + f.height_px + 14) << "\" text-anchor=\"middle\">" << Label(x)
        << "</text>\n";
  }
  for (double y = std::ceil(f.min_y / step_y) * step_y; y <= f.max_y; y += step_y) {
    svg << "<line x1=\"" << Num(f.left_px) << "\" y1=\"" << Num(f.PxY(y)) << "\" x2=\""
        << Num(f.left_px + f.width_px) << "\" y2=\"" << Num(f.PxY(y)) << "\" stroke=\"#e4e4e4\"/>\n<text x=\""
        << Num(f.left_px - 4) << "\" y=\"" << Num(f.PxY(y) + 4) << "\" text-anchor=\"end\">" << Label(y)
        << "</text>\n";
  }
  svg << "<text x=\"" << Num(f.left_px + f.width_px / 2) << "\" y=\"" << Num(f.top_px + f.height_px + 30)
      << "\" text-anchor=\"middle\">" << Escape(x_title) << "</text>\n<text x=\"14\" y=\""
      << Num(f.top_px + f.height_px / 2) << "\" text-anchor=\"middle\" transform=\"rotate(-90 14 "
      << Num(f.top_px + f.height_px / 2) << ")\">" << Escape(y_title) << "</text>\n";
}

void DrawPolyline(const Frame& f, const std::vector<Eigen::Vector2d>& points, const char* color,
                  std::ostringstream& svg) {
  if (points.empty()) return;
  const size_t stride = std::max<size_t>(1, points.size() / kMaxPolylinePoints);
  svg << "<polyline fill=\"none\" stroke=\"" << color << "\" stroke-width=\"1.5\" points=\"";
  for (size_t i = 0; i < points.size(); i += stride)
    svg << Num(f.PxX(points[i].x())) << "," << Num(f.PxY(points[i].y())) << " ";
  svg << Num(f.PxX(points.back().x())) << "," << Num(f.PxY(points.back().y())) << "\"/>\n";
}

std::vector<Eigen::Vector2d> Xy(const Trajectory& trajectory) {
  std::vector<Eigen::Vector2d> points;
  for (const StampedSE3& pose : trajectory) points.push_back(pose.T.translation().head<2>());
  return points;
}

void DrawMarkers(const Frame& f, const std::vector<PlotMarker>& markers, std::ostringstream& svg) {
  for (const PlotMarker& m : markers) {
    if (m.p_true && m.p_est) {
      svg << "<line x1=\"" << Num(f.PxX(m.p_true->x())) << "\" y1=\"" << Num(f.PxY(m.p_true->y()))
          << "\" x2=\"" << Num(f.PxX(m.p_est->x())) << "\" y2=\"" << Num(f.PxY(m.p_est->y()))
          << "\" stroke=\"#d62728\" stroke-width=\"0.8\"/>\n";
    }
    if (m.p_true) {
      svg << "<rect x=\"" << Num(f.PxX(m.p_true->x()) - 4) << "\" y=\"" << Num(f.PxY(m.p_true->y()) - 4)
          << "\" width=\"8\" height=\"8\" fill=\"none\" stroke=\"black\"><title>" << Escape(m.label)
          << " (true)</title></rect>\n";
    }
    if (m.p_est) {
      const double x = f.PxX(m.p_est->x()), y = f.PxY(m.p_est->y());
      svg << "<path d=\"M" << Num(x - 4) << "," << Num(y - 4) << " L" << Num(x + 4) << "," << Num(y + 4)
          << " M" << Num(x - 4) << "," << Num(y + 4) << " L" << Num(x + 4) << "," << Num(y - 4)
          << "\" stroke=\"#d62728\" stroke-width=\"1.5\"><title>" << Escape(m.label)
          << " (estimate)</title></path>\n";
    }
  }
}

void DrawLegend(double x, double y, const std::vector<std::pair<std::string, std::string>>& entries,
                std::ostringstream& svg) {
  for (const auto& [color, text] : entries) {
    svg << "<line x1=\"" << Num(x) << "\" y1=\"" << Num(y - 4) << "\" x2=\"" << Num(x + 18) << "\" y2=\""
        << Num(y - 4) << "\" stroke=\"" << color << "\" stroke-width=\"3\"/>\n<text x=\"" << Num(x + 22)
        << "\" y=\"" << Num(y) << "\">" << Escape(text) << "</text>\n";
    x += 30 + 7.0 * static_cast<double>(text.size());
  }
}

void DrawTopView(const PlotInput& input, std::ostringstream& svg) {
  Bounds bounds;
  std::vector<Eigen::Vector2d> gt_xy, est_xy;
  if (input.trajectory) {
    gt_xy = Xy(input.trajectory->gt_associated);
    est_xy = Xy(input.trajectory->est_aligned);
  }
  for (const auto* points : {&gt_xy, &est_xy}) {
    for (const Eigen::Vector2d& p : *points) bounds.Add(p.x(), p.y());
  }
  for (const PlotMarker& m : input.markers) {
    for (const auto* p : {&m.p_true, &m.p_est}) {
      if (*p) bounds.Add((*p)->x(), (*p)->y());
    }
  }
  if (bounds.Empty()) throw std::invalid_argument("plot: nothing to draw");
  const Frame frame = TopViewFrame(bounds);
  DrawAxes(frame, "x (m)", "y (m)", svg);
  DrawPolyline(frame, gt_xy, "#2ca02c", svg);
  DrawPolyline(frame, est_xy, "#1f77b4", svg);
  DrawMarkers(frame, input.markers, svg);
  DrawLegend(kLeftPx, kTopViewTopPx - 8,
             {{"#2ca02c", "ground truth"},
              {"#1f77b4", "estimate (aligned)"},
              {"#d62728", "markers: estimate x, true []"}},
             svg);
}

// Time runs from the first stamp (epoch stamps would make unreadable tick labels).
void DrawErrorPanel(const TrajectoryEvaluation& e, std::ostringstream& svg) {
  const std::vector<double>& t = e.ate.stamps_s;
  double max_error_m = e.ate.translation_m.max;
  double t0 = t.front(), t1 = t.back();
  if (e.pe_te) {
    max_error_m = std::max(max_error_m, e.pe_te->position_m.max);
    t0 = std::min(t0, e.pe_te->stamps_s.front());
    t1 = std::max(t1, e.pe_te->stamps_s.back());
  }
  const Frame f{0.0,
                t1 > t0 ? t1 - t0 : 1.0,
                0.0,
                max_error_m > 0.0 ? 1.1 * max_error_m : 1.0,
                kLeftPx,
                kErrorTopPx,
                kWidthPx - kLeftPx - kRightPx,
                kErrorHeightPx};
  char axis_title[96];
  std::snprintf(axis_title, sizeof(axis_title), "time (s) since t0 = %.3f s", t0);
  DrawAxes(f, axis_title, "error (m)", svg);
  std::vector<Eigen::Vector2d> points;
  for (size_t i = 0; i < t.size(); ++i) points.emplace_back(t[i] - t0, e.ate.translation_errors_m[i]);
  DrawPolyline(f, points, "#1f77b4", svg);
  std::vector<std::pair<std::string, std::string>> legend = {{"#1f77b4", "ATE translation error"}};
  if (e.pe_te) {
    for (size_t k = 0; k < e.pe_te->stamps_s.size(); ++k) {
      svg << "<circle cx=\"" << Num(f.PxX(e.pe_te->stamps_s[k] - t0)) << "\" cy=\""
          << Num(f.PxY(e.pe_te->position_errors_m[k])) << "\" r=\"2.5\" fill=\"#ff7f0e\"/>\n";
    }
    legend.push_back({"#ff7f0e", "PE before each correction"});
  }
  DrawLegend(kLeftPx, kErrorTopPx - 8, legend, svg);
}

}  // namespace

std::vector<PlotMarker> PlotMarkersFromMaps(const MarkerMap* est, const Sim3Alignment& alignment,
                                            const MarkerMap* truth) {
  std::map<MarkerKey, PlotMarker> by_key;
  if (truth) {
    for (const MapMarker& m : truth->markers) by_key[m.key].p_true = m.T_world_marker.translation();
  }
  if (est) {
    for (const MapMarker& m : est->markers)
      by_key[m.key].p_est = alignment.Apply(m.T_world_marker.translation());
  }
  std::vector<PlotMarker> markers;
  for (auto& [key, marker] : by_key) {
    marker.label = key.ToString();
    markers.push_back(marker);
  }
  return markers;
}

std::vector<PlotMarker> PlotMarkersFromMapEval(const MarkerMap& est, const MarkerMap& truth,
                                               const MapEvalResult& result) {
  std::map<int, Sim3Alignment> alignments;
  for (const ComponentResult& c : result.components) alignments[c.component] = c.alignment;
  std::vector<PlotMarker> markers = PlotMarkersFromMaps(nullptr, Sim3Alignment(), &truth);
  for (const MapMarker& m : est.markers) {
    const Eigen::Vector3d p_gt = alignments[m.component.value_or(0)].Apply(m.T_world_marker.translation());
    const auto it = std::find_if(markers.begin(), markers.end(),
                                 [&](const PlotMarker& p) { return p.label == m.key.ToString(); });
    if (it != markers.end()) {
      it->p_est = p_gt;
    } else {
      markers.push_back({m.key.ToString(), std::nullopt, p_gt});
    }
  }
  return markers;
}

std::string RenderSvg(const PlotInput& input) {
  const bool with_errors = input.trajectory != nullptr;
  const double height_px =
      with_errors ? kErrorTopPx + kErrorHeightPx + 45 : kTopViewTopPx + kTopViewHeightPx + 45;
  std::ostringstream svg;
  svg << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\""
      << Num(kWidthPx) << "\" height=\"" << Num(height_px) << "\" viewBox=\"0 0 " << Num(kWidthPx) << " "
      << Num(height_px) << "\" font-family=\"sans-serif\" font-size=\"11\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"#fafafa\"/>\n<text x=\"" << Num(kLeftPx)
      << "\" y=\"20\" font-size=\"14\">" << Escape(input.title) << "</text>\n";
  DrawTopView(input, svg);
  if (with_errors) DrawErrorPanel(*input.trajectory, svg);
  svg << "</svg>\n";
  return svg.str();
}

}  // namespace waymark::eval
