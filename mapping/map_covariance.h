// The markers' joint map uncertainty in a compact form: a low-rank factor shared by all markers.
//
// The marginal covariance Sigma_ii of each marker (map.json `covariance`) drops the correlation
// between markers. Neighbouring markers share the survey's drift, so their errors are strongly
// correlated; a filter that takes them as independent averages the shared error away and grows
// overconfident (docs/online.md, consistency). With n = 6 N marker tangent coordinates (right
// perturbation, [r, t] per marker, geometry/pose.h) the joint covariance is approximated as
//   Sigma ~ F F^T + blockdiag(D_i),   F = V_k Lambda_k^(1/2)   (n x k),   D_i = Sigma_ii - F_i F_i^T,
// V_k, Lambda_k the k largest eigenpairs of Sigma (the long-wavelength drift modes), F_i the six
// rows of marker i (map.json `covariance_factor`, docs/formats.md). Equivalently the marker error
// is eps_i = F_i xi + eta_i with xi ~ N(0, I_k) shared by every marker and eta_i ~ N(0, D_i)
// independent: exact for the k modes, marker-to-marker correlation outside them dropped.
//
// Sigma is the marker block of the inverse of the Gauss-Newton information H = J^T J of the
// final (non-robust) problem over all its free blocks (frames, markers, odometry calibration),
// in the gauge of its constant blocks (anchors). It is never formed: a product Sigma_m v is one
// solve with the sparse LDL^T of H that also gives the marginals (InformationFactor),
//   Sigma_m v = B P (H^-1 P^T B^T v),   P: selects the markers' manifold coordinates,
//   B = blockdiag(ManifoldToBodyTangentJacobian(T_i))  (manifold -> body tangent, factors/pose_block.h),
// and the top k eigenpairs come from a randomized subspace iteration (Halko et al. 2011):
//   Y = Sigma Omega (Omega: n x (k + p) Gaussian, fixed seed), q times Q = orth(Y), Y = Sigma Q;
//   Q = orth(Y),  Q^T Sigma Q = U Lambda U^T,  F = Q U_k Lambda_k^(1/2).
// An approximate subspace can leave F_i F_i^T slightly above Sigma_ii; the rows of such a marker are
// scaled by s_i = min(1, lambda_max(F_i^T Sigma_ii^-1 F_i)^(-1/2)) so that every D_i stays PSD.
#pragma once

#include <ceres/crs_matrix.h>
#include <ceres/problem.h>

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"
#include "mapping/marginal_covariance.h"

namespace waymark {

struct CovarianceFactorOptions {
  int rank = 20;             // k: columns of F (at most n)
  int oversampling = 10;     // p: extra columns of the subspace iteration
  int power_iterations = 6;  // q
  std::uint64_t seed = 1;    // of Omega
};

// The rows F_i (6 x k) of every marker block, in the order of `marker_blocks` (7-blocks of
// factors/pose_block.h, free in `problem`), given their marginals Sigma_ii (the map's
// `covariance`, body tangent) and poses T_i. nullopt when H is not positive definite (a free
// gauge) or the inputs disagree in length. k = min(rank, 6 N).
std::optional<std::vector<CovarianceFactor>> MarkerCovarianceFactors(
    ceres::Problem* problem, const std::vector<const double*>& marker_blocks,
    const std::vector<SE3d>& T_world_marker, const std::vector<Matrix6d>& marginal,
    const CovarianceFactorOptions& options);

// The same with the factorization of H made once for the marginals (mapping/marginal_covariance.h).
std::optional<std::vector<CovarianceFactor>> MarkerCovarianceFactors(
    const InformationFactor& information, const std::vector<const double*>& marker_blocks,
    const std::vector<SE3d>& T_world_marker, const std::vector<Matrix6d>& marginal,
    const CovarianceFactorOptions& options);

// The largest k eigenpairs of a symmetric PSD operator y = apply(x) on R^n by the randomized
// subspace iteration above; returns F = V_k Lambda_k^(1/2) (n x k).
Eigen::MatrixXd TopEigenFactor(const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& apply, int n,
                               const CovarianceFactorOptions& options);

// Scales F_i so that Sigma_ii - F_i F_i^T is PSD (see the header comment); returns s_i.
double FitFactorToMarginal(const Matrix6d& marginal, CovarianceFactor* factor);

}  // namespace waymark
