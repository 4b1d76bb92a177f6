#include "plan/survey.h"

#include <map>
#include <stdexcept>

#include "runner/run.h"

namespace waymark::plan {

std::vector<SurveyPose> LocalizeSurvey(const Dataset& survey, const MarkerMap& map) {
  if (survey.config.motion != MotionModel::kPlanar) {
    throw std::invalid_argument(
        "the survey is not planar (dataset.yaml motion: free): routes are for planar robots");
  }
  if (survey.odometry.empty()) throw std::invalid_argument("the survey has no odometry");
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(survey);
  const LocalizeRun run = RunLocalizer(survey, map, options);
  std::map<std::pair<double, std::string>, const DetectionFrame*> frames;
  for (const DetectionFrame& frame : survey.detections) frames[{frame.stamp_s, frame.camera}] = &frame;
  std::vector<SurveyPose> poses;
  int component = 0;
  for (size_t i = 0; i < run.outputs.size(); ++i) {
    const PoseOutput& out = run.outputs[i];
    if (out.tracking != TrackingStatus::kTracking || !out.T_world_robot || !out.covariance) continue;
    if (poses.empty() || poses.back().stamp_s != out.stamp_s) poses.emplace_back();
    SurveyPose& pose = poses.back();
    pose.stamp_s = out.stamp_s;
    const SE3d& T = *out.T_world_robot;
    pose.x_y_yaw = Eigen::Vector3d(T.translation().x(), T.translation().y(), T.yaw());
    pose.covariance = out.covariance->topLeftCorner<3, 3>();
    if (const auto it = frames.find({out.stamp_s, run.cameras[i]}); it != frames.end()) {
      for (const MarkerObservation& m : it->second->markers) {
        const MapMarker* marker = map.Find(m.key);
        if (!marker) continue;
        pose.codes.insert(m.key);
        component = marker->component.value_or(0);
      }
    }
    pose.component = component;
  }
  return poses;
}

OdometryNoise SurveyOdometryNoise(const Dataset& survey) { return DefaultLocalizerOptions(survey).odometry; }

}  // namespace waymark::plan
