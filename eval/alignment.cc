#include "eval/alignment.h"

#include <Eigen/SVD>
#include <limits>
#include <stdexcept>

namespace waymark::eval {
namespace {

template <int kDim>
struct UmeyamaFit {
  Eigen::Matrix<double, kDim, kDim> R;
  Eigen::Matrix<double, kDim, 1> t;
  double scale = 1.0;
};

// Umeyama (1991), eq. 34-43, in kDim dimensions: dst ~ scale * R * src + t.
template <int kDim>
UmeyamaFit<kDim> Umeyama(const std::vector<Eigen::Matrix<double, kDim, 1>>& src,
                         const std::vector<Eigen::Matrix<double, kDim, 1>>& dst, bool with_scale) {
  using Vector = Eigen::Matrix<double, kDim, 1>;
  using Matrix = Eigen::Matrix<double, kDim, kDim>;
  const double n = static_cast<double>(src.size());
  Vector mean_src = Vector::Zero(), mean_dst = Vector::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    mean_src += src[i] / n;
    mean_dst += dst[i] / n;
  }
  double sigma_src = 0.0;
  Matrix cov = Matrix::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    sigma_src += (src[i] - mean_src).squaredNorm() / n;
    cov += (dst[i] - mean_dst) * (src[i] - mean_src).transpose() / n;
  }
  Eigen::JacobiSVD<Matrix> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vector d = svd.singularValues();
  // Rank test relative to the largest singular value (evo uses an absolute machine epsilon).
  const double tolerance = 1e-10 * std::max(d(0), std::numeric_limits<double>::min());
  int rank = 0;
  for (int i = 0; i < kDim; ++i) rank += d(i) > tolerance ? 1 : 0;
  if (d(0) <= 0.0 || rank < kDim - 1) {
    throw DegenerateAlignmentError("degenerate point configuration (all points equal" +
                                   std::string(kDim == 3 ? " or on one line" : "") +
                                   "): the alignment is not defined; use --align none or more poses");
  }
  Vector s_diag = Vector::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s_diag(kDim - 1) = -1.0;
  UmeyamaFit<kDim> fit;
  fit.R = svd.matrixU() * s_diag.asDiagonal() * svd.matrixV().transpose();
  fit.scale = with_scale ? d.dot(s_diag) / sigma_src : 1.0;
  fit.t = mean_dst - fit.scale * fit.R * mean_src;
  return fit;
}

void CheckSizes(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst) {
  if (src.size() != dst.size()) throw std::invalid_argument("alignment: point lists differ in size");
  if (src.size() < 2) throw std::invalid_argument("alignment: needs at least 2 point pairs");
}

}  // namespace

const char* AlignmentModeName(AlignmentMode mode) {
  switch (mode) {
    case AlignmentMode::kNone:
      return "none";
    case AlignmentMode::kSE3:
      return "se3";
    case AlignmentMode::kSE2:
      return "se2";
    case AlignmentMode::kOrigin:
      return "origin";
  }
  return "unknown";
}

AlignmentMode ParseAlignmentMode(const std::string& name) {
  if (name == "none") return AlignmentMode::kNone;
  if (name == "se3") return AlignmentMode::kSE3;
  if (name == "se2") return AlignmentMode::kSE2;
  if (name == "origin") return AlignmentMode::kOrigin;
  throw std::invalid_argument("alignment '" + name + "': expected se3, se2, origin or none");
}

SE3d Sim3Alignment::Apply(const SE3d& T_est_robot) const {
  return SE3d(Eigen::Matrix3d(R_gt_est * T_est_robot.rotation_matrix()), Apply(T_est_robot.translation()));
}

Trajectory Sim3Alignment::Apply(const Trajectory& trajectory_est) const {
  Trajectory out;
  out.reserve(trajectory_est.size());
  for (const StampedSE3& pose : trajectory_est) out.push_back({pose.stamp_s, Apply(pose.T)});
  return out;
}

Sim3Alignment UmeyamaSim3(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                          bool with_scale) {
  CheckSizes(src, dst);
  const UmeyamaFit<3> fit = Umeyama<3>(src, dst, with_scale);
  Sim3Alignment alignment;
  alignment.R_gt_est = fit.R;
  alignment.t_gt_est = fit.t;
  alignment.scale = fit.scale;
  return alignment;
}

Sim3Alignment UmeyamaSE2(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                         bool with_scale) {
  CheckSizes(src, dst);
  std::vector<Eigen::Vector2d> src_xy, dst_xy;
  for (size_t i = 0; i < src.size(); ++i) {
    src_xy.push_back(src[i].head<2>());
    dst_xy.push_back(dst[i].head<2>());
  }
  const UmeyamaFit<2> fit = Umeyama<2>(src_xy, dst_xy, with_scale);
  Sim3Alignment alignment;
  alignment.R_gt_est.topLeftCorner<2, 2>() = fit.R;
  alignment.t_gt_est.head<2>() = fit.t;
  alignment.scale = fit.scale;
  return alignment;
}

Sim3Alignment AlignOrigin(const SE3d& T_gt_robot, const SE3d& T_est_robot) {
  const SE3d T_gt_est = T_gt_robot * T_est_robot.inverse();
  Sim3Alignment alignment;
  alignment.R_gt_est = T_gt_est.rotation_matrix();
  alignment.t_gt_est = T_gt_est.translation();
  return alignment;
}

Sim3Alignment ComputeAlignment(AlignmentMode mode, bool with_scale, const std::vector<Eigen::Vector3d>& src,
                               const std::vector<Eigen::Vector3d>& dst) {
  switch (mode) {
    case AlignmentMode::kSE3:
      return UmeyamaSim3(src, dst, with_scale);
    case AlignmentMode::kSE2:
      return UmeyamaSE2(src, dst, with_scale);
    case AlignmentMode::kOrigin:
      throw std::invalid_argument("alignment origin needs poses, not positions");
    case AlignmentMode::kNone:
      break;
  }
  Sim3Alignment alignment;
  if (with_scale) alignment.scale = UmeyamaSim3(src, dst, true).scale;
  return alignment;
}

std::vector<Eigen::Vector3d> Positions(const Trajectory& trajectory) {
  std::vector<Eigen::Vector3d> positions;
  positions.reserve(trajectory.size());
  for (const StampedSE3& pose : trajectory) positions.push_back(pose.T.translation());
  return positions;
}

}  // namespace waymark::eval
