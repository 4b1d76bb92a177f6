#include "mapping/multi_survey.h"

#include <algorithm>
#include <limits>
#include <set>
#include <stdexcept>

#include "geometry/board.h"
#include "util/format.h"

namespace waymark {
namespace {

// First and last stamp of everything the dataset holds with a time.
std::pair<double, double> Span(const Dataset& dataset) {
  double begin = std::numeric_limits<double>::infinity(), end = -begin;
  const auto add = [&](double t) {
    begin = std::min(begin, t);
    end = std::max(end, t);
  };
  for (const StampedSE3& pose : dataset.odometry) add(pose.stamp_s);
  for (const DetectionFrame& frame : dataset.detections) add(frame.stamp_s);
  for (const ImageEntry& image : dataset.images) add(image.stamp_s);
  if (!(begin <= end))
    throw std::runtime_error(dataset.config.name + ": nothing with a stamp (no odometry, no detections)");
  return {begin, end};
}

bool SameSigma(const std::optional<OdometrySigma>& a, const std::optional<OdometrySigma>& b) {
  if (!a || !b) return !a && !b;
  return a->trans_per_m == b->trans_per_m && a->rot_per_rad == b->rot_per_rad &&
         a->trans_per_sqrt_s == b->trans_per_sqrt_s && a->rot_per_sqrt_s == b->rot_per_sqrt_s &&
         a->trans_per_sqrt_m == b->trans_per_sqrt_m && a->rot_per_sqrt_m == b->rot_per_sqrt_m;
}

}  // namespace

CombinedSurvey CombineSurveys(const std::vector<const Dataset*>& datasets, double gap_s) {
  if (datasets.empty()) throw std::runtime_error("no dataset to combine");
  CombinedSurvey combined;
  Dataset& out = combined.dataset;
  const Dataset& first = *datasets.front();
  out.dir = first.dir;
  out.config = first.config;
  out.config.name = first.config.name;
  out.config.cameras.clear();
  out.has_odometry_file = out.has_detections_file = out.has_images_file = false;
  std::set<std::string> names;
  double next_begin_s = 0.0;
  for (size_t k = 0; k < datasets.size(); ++k) {
    const Dataset& d = *datasets[k];
    const std::string& name = d.config.name;
    if (!names.insert(name).second)
      throw std::runtime_error("two datasets are named " + name + " (dataset.yaml name)");
    const auto disagree = [&](const std::string& what) {
      throw std::runtime_error(name + ": " + what + " differs from " + first.config.name + "'s");
    };
    if (d.config.motion != first.config.motion) disagree("motion");
    if (d.config.default_marker_size_m != first.config.default_marker_size_m)
      disagree("default_marker_size_m");
    if (!SameSigma(d.config.odometry_sigma, first.config.odometry_sigma)) disagree("odometry_sigma");
    if (d.config.payload.has_value() != first.config.payload.has_value() ||
        (d.config.payload && (d.config.payload->pattern != first.config.payload->pattern ||
                              d.config.payload->fields != first.config.payload->fields)))
      disagree("payload");
    const auto [begin_s, end_s] = Span(d);
    SurveyPart part;
    part.name = name;
    part.offset_s = k == 0 ? 0.0 : next_begin_s - begin_s;
    part.begin_s = begin_s + part.offset_s;
    part.end_s = end_s + part.offset_s;
    next_begin_s = part.end_s + gap_s;
    const std::string prefix = name + ".";
    for (const std::string& camera : d.config.cameras) {
      CameraInfo info = d.cameras.at(camera);
      info.name = prefix + camera;
      out.config.cameras.push_back(info.name);
      out.cameras[info.name] = info;
    }
    for (StampedSE3 pose : d.odometry) {
      pose.stamp_s += part.offset_s;
      out.odometry.push_back(pose);
    }
    for (DetectionFrame frame : d.detections) {
      frame.stamp_s += part.offset_s;
      frame.camera = prefix + frame.camera;
      out.detections.push_back(std::move(frame));
    }
    for (ImageEntry image : d.images) {
      image.stamp_s += part.offset_s;
      image.camera = prefix + image.camera;
      image.path = (d.dir / image.path).string();
      out.images.push_back(std::move(image));
    }
    out.has_odometry_file |= d.has_odometry_file;
    out.has_detections_file |= d.has_detections_file;
    out.has_images_file |= d.has_images_file;
    if (d.known_markers) {
      if (!out.known_markers) out.known_markers = MarkerMap{};
      for (const MapMarker& marker : d.known_markers->markers) {
        const MapMarker* existing = out.known_markers->Find(marker.key);
        if (existing == nullptr) {
          out.known_markers->markers.push_back(marker);
        } else if (existing->size_m != marker.size_m || existing->has_pose != marker.has_pose ||
                   existing->fixed != marker.fixed ||
                   (existing->has_pose &&
                    !(existing->T_world_marker.translation() == marker.T_world_marker.translation() &&
                      existing->T_world_marker.rotation().coeffs() ==
                          marker.T_world_marker.rotation().coeffs()))) {
          throw std::runtime_error(name + ": markers.json entry " + marker.key.ToString() +
                                   " differs from the same code's entry in an earlier dataset");
        }
      }
      // Rigid boards (mapping/boards.h): one of each name; the same name must be the same board.
      for (const MapBoard& board : d.known_markers->boards) {
        const auto same = std::find_if(out.known_markers->boards.begin(), out.known_markers->boards.end(),
                                       [&](const MapBoard& b) { return b.name == board.name; });
        if (same == out.known_markers->boards.end()) {
          out.known_markers->boards.push_back(board);
          continue;
        }
        bool equal = same->members.size() == board.members.size() && same->has_pose == board.has_pose &&
                     same->fixed == board.fixed;
        for (size_t i = 0; equal && i < board.members.size(); ++i) {
          equal = same->members[i].key == board.members[i].key &&
                  same->members[i].T_board_marker.translation() ==
                      board.members[i].T_board_marker.translation() &&
                  same->members[i].T_board_marker.rotation().coeffs() ==
                      board.members[i].T_board_marker.rotation().coeffs();
        }
        if (!equal)
          throw std::runtime_error(name + ": markers.json board " + board.name +
                                   " differs from the same board in an earlier dataset");
      }
      if (const std::optional<BoardProblem> problem = FindBoardProblem(*out.known_markers))
        throw std::runtime_error(name + ": markers.json board " +
                                 out.known_markers->boards[problem->board].name +
                                 " with the earlier datasets' boards: " + problem->message);
    }
    for (const auto& [reason, count] : d.warnings.counts) out.warnings.counts[reason] += count;
    combined.parts.push_back(part);
  }
  // Detections sorted by stamp (each part's are already; parts follow each other in time).
  return combined;
}

std::map<std::string, Trajectory> SplitTrajectory(const CombinedSurvey& combined,
                                                  const Trajectory& trajectory) {
  std::map<std::string, Trajectory> parts;
  for (const SurveyPart& part : combined.parts) {
    Trajectory& own = parts[part.name];
    for (const StampedSE3& pose : trajectory) {
      if (pose.stamp_s >= part.begin_s - 1e-9 && pose.stamp_s <= part.end_s + 1e-9)
        own.push_back({pose.stamp_s - part.offset_s, pose.T});
    }
  }
  return parts;
}

}  // namespace waymark
