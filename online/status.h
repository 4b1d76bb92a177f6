// Status codes the localizer returns instead of throwing or aborting on bad data at run time.
#pragma once

namespace waymark {

// Outcome of one call into the filter (a prediction, an update, a frame).
enum class StepStatus {
  kOk,
  kTimeWentBackwards,    // stamp older than the last one processed: input ignored
  kInvalidInput,         // non-finite numbers, negative dt, wrong motion model for the input
  kUnknownCamera,        // a frame from a camera the localizer was not given
  kNotPositiveDefinite,  // S = H P H^T + R could not be factored (LLT failed)
  kNonFiniteCovariance,  // the new P would hold NaN/inf: the old P is kept, the filter is lost
};

// Whether the pose output can be trusted.
enum class TrackingStatus {
  kUninitialized,  // no code seen yet: no pose
  kTracking,       // pose and covariance are valid
  kSuspect,        // the last frame's codes all contradicted the track: no pose until codes agree
                   // with it again (kTracking), confirm another pose (relocalized) or it is lost
  kLost,           // kidnapped, diverged or numerically broken: no pose until relocalized
};

inline const char* StepStatusName(StepStatus status) {
  switch (status) {
    case StepStatus::kOk:
      return "ok";
    case StepStatus::kTimeWentBackwards:
      return "time went backwards";
    case StepStatus::kInvalidInput:
      return "invalid input";
    case StepStatus::kUnknownCamera:
      return "unknown camera";
    case StepStatus::kNotPositiveDefinite:
      return "innovation covariance not positive definite";
    case StepStatus::kNonFiniteCovariance:
      return "non-finite covariance";
  }
  return "?";
}

inline const char* TrackingStatusName(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kUninitialized:
      return "uninitialized";
    case TrackingStatus::kTracking:
      return "tracking";
    case TrackingStatus::kSuspect:
      return "suspect";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "?";
}

}  // namespace waymark
