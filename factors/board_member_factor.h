// A residual of a code on a rigid board, on the board's pose (geometry/board.h): any residual
// whose last parameter block is the code's pose T_world_marker (an SE(3) block, factors/
// pose_block.h) is evaluated at
//
//   T_world_marker = T_world_board * T_board_marker
//
// with T_board_marker the board's constant layout, so the code's residuals move the board's one
// pose block instead of a block of the code's own: the board stays rigid by construction, with
// no soft constraint between its codes.
//
// Blocks: those of the wrapped residual, the last one replaced by T_world_board
// [qx qy qz qw tx ty tz] (manifold SE3Manifold). Jacobian of the last block by the chain rule in
// the blocks' ambient coordinates, d r / d B = (d r / d M)(d M / d B), with the 7 x 7
// d M / d B of the composition above evaluated on ceres::Jet (exact; M's quaternion is
// q_B q_C, linear in q_B, and t_M = R(q_B) t_C + t_B). The wrapped residual's behaviour
// behind the camera is kept (factors/corner_observation.h).
#pragma once

#include <ceres/cost_function.h>
#include <ceres/jet.h>

#include <array>
#include <memory>
#include <vector>

#include "factors/pose_block.h"

namespace waymark {

// M = B * C on 7-blocks [qx qy qz qw tx ty tz], on any scalar.
template <typename T>
void ComposeBoardMemberBlock(const T* T_world_board, const SE3d& T_board_marker, T* T_world_marker) {
  const SE3T<T> M = SE3TFromBlock(T_world_board) * SE3TFromSE3<T>(T_board_marker);
  T_world_marker[0] = M.q.x();
  T_world_marker[1] = M.q.y();
  T_world_marker[2] = M.q.z();
  T_world_marker[3] = M.q.w();
  for (int i = 0; i < 3; ++i) T_world_marker[4 + i] = M.t[i];
}

class BoardMemberCost : public ceres::CostFunction {
 public:
  // Takes ownership of `inner`, whose last parameter block must be an SE(3) pose block.
  BoardMemberCost(ceres::CostFunction* inner, const SE3d& T_board_marker)
      : inner_(inner), T_board_marker_(T_board_marker) {
    set_num_residuals(inner_->num_residuals());
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const size_t blocks = inner_->parameter_block_sizes().size();
    const size_t last = blocks - 1;
    using Jet = ceres::Jet<double, kSE3BlockSize>;
    std::array<Jet, kSE3BlockSize> board, marker_jet;
    for (int i = 0; i < kSE3BlockSize; ++i) board[i] = Jet(parameters[last][i], i);
    ComposeBoardMemberBlock(board.data(), T_board_marker_, marker_jet.data());
    std::array<double, kSE3BlockSize> marker;
    for (int i = 0; i < kSE3BlockSize; ++i) marker[i] = marker_jet[i].a;
    std::vector<const double*> inner_parameters(parameters, parameters + blocks);
    inner_parameters[last] = marker.data();
    const bool want_last = jacobians != nullptr && jacobians[last] != nullptr;
    const int n = num_residuals();
    std::vector<double> d_r_d_marker(want_last ? n * kSE3BlockSize : 0);
    std::vector<double*> inner_jacobians;
    if (jacobians != nullptr) {
      inner_jacobians.assign(jacobians, jacobians + blocks);
      inner_jacobians[last] = want_last ? d_r_d_marker.data() : nullptr;
    }
    if (!inner_->Evaluate(inner_parameters.data(), residuals,
                          jacobians != nullptr ? inner_jacobians.data() : nullptr))
      return false;
    if (want_last) {
      // Row-major n x 7 times 7 x 7 (d M_i / d B_k = marker_jet[i].v[k]).
      for (int r = 0; r < n; ++r) {
        for (int k = 0; k < kSE3BlockSize; ++k) {
          double sum = 0.0;
          for (int i = 0; i < kSE3BlockSize; ++i)
            sum += d_r_d_marker[r * kSE3BlockSize + i] * marker_jet[i].v[k];
          jacobians[last][r * kSE3BlockSize + k] = sum;
        }
      }
    }
    return true;
  }

 private:
  const std::unique_ptr<ceres::CostFunction> inner_;
  const SE3d T_board_marker_;
};

}  // namespace waymark
