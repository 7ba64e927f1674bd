// Quaternions as the official UP-LVSM uses them: scalar-LAST (qx, qy, qz, qw) in the 7-D pose encoding.
// All functions take and return tensors with arbitrary leading dimensions.
#pragma once
#include <torch/torch.h>

namespace uplvsm::geometry {

// [..., 4] (x, y, z, w) -> [..., 3, 3]. Uses s = 2 / (q.q), so q need not be unit length (official quat_to_mat).
torch::Tensor quat_to_rotation(const torch::Tensor& q_xyzw);

// [..., 3, 3] -> [..., 4] (x, y, z, w) with w >= 0 (pytorch3d's matrix_to_quaternion, as the official code).
torch::Tensor rotation_to_quat(const torch::Tensor& R);

// Shortest-path spherical interpolation of unit quaternions [..., 4] (xyzw) at fraction t in [0, 1].
torch::Tensor quat_slerp(const torch::Tensor& q0, const torch::Tensor& q1, double t);

// The Hamilton product a ⊗ b of [..., 4] (xyzw): the rotation of a followed, in a's own frame, by b's
// (quat_to_rotation(a ⊗ b) = quat_to_rotation(a) quat_to_rotation(b)); lengths multiply.
torch::Tensor quat_multiply(const torch::Tensor& a, const torch::Tensor& b);

// q / max(|q|, eps), computed in fp32 and cast back (official estimator head).
torch::Tensor normalize_quat(const torch::Tensor& q, double eps = 1e-3);

}  // namespace uplvsm::geometry
