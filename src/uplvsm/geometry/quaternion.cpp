#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::geometry {

using torch::indexing::Slice;

torch::Tensor quat_to_rotation(const torch::Tensor& q) {
  TORCH_CHECK(q.size(-1) == 4, "quat_to_rotation: expected [..., 4] quaternions, got ", q.sizes());
  auto i = q.select(-1, 0), j = q.select(-1, 1), k = q.select(-1, 2), r = q.select(-1, 3);
  auto s = 2.0 / (q * q).sum(-1);
  auto o = torch::stack(
      {1 - s * (j * j + k * k), s * (i * j - k * r), s * (i * k + j * r), s * (i * j + k * r), 1 - s * (i * i + k * k),
       s * (j * k - i * r), s * (i * k - j * r), s * (j * k + i * r), 1 - s * (i * i + j * j)},
      -1);
  auto shape = q.sizes().vec();
  shape.back() = 3;
  shape.push_back(3);
  return o.reshape(shape);
}

torch::Tensor rotation_to_quat(const torch::Tensor& R) {
  TORCH_CHECK(R.dim() >= 2 && R.size(-1) == 3 && R.size(-2) == 3, "rotation_to_quat: expected [..., 3, 3], got ",
              R.sizes());
  auto batch = R.sizes().slice(0, R.dim() - 2).vec();
  auto m = R.reshape({-1, 9});
  auto m00 = m.select(1, 0), m01 = m.select(1, 1), m02 = m.select(1, 2);
  auto m10 = m.select(1, 3), m11 = m.select(1, 4), m12 = m.select(1, 5);
  auto m20 = m.select(1, 6), m21 = m.select(1, 7), m22 = m.select(1, 8);
  // sqrt(max(0, x)) with a zero subgradient at 0, as pytorch3d's _sqrt_positive_part.
  auto sqrt_pos = [](const torch::Tensor& x) {
    return torch::where(x > 0, torch::sqrt(x.clamp_min(1e-30)), torch::zeros_like(x));
  };
  auto q_abs =
      sqrt_pos(torch::stack({1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22}, -1));
  // Candidates (w, x, y, z) scaled by each |component|; the best-conditioned one is picked.
  auto cand = torch::stack({torch::stack({q_abs.select(1, 0).pow(2), m21 - m12, m02 - m20, m10 - m01}, -1),
                            torch::stack({m21 - m12, q_abs.select(1, 1).pow(2), m10 + m01, m02 + m20}, -1),
                            torch::stack({m02 - m20, m10 + m01, q_abs.select(1, 2).pow(2), m12 + m21}, -1),
                            torch::stack({m10 - m01, m20 + m02, m21 + m12, q_abs.select(1, 3).pow(2)}, -1)},
                           1);  // [N, 4, 4]
  auto denom = 2.0 * q_abs.unsqueeze(-1).clamp_min(0.1);
  cand = cand / denom;
  auto best = q_abs.argmax(-1);
  auto wxyz = cand.gather(1, best.view({-1, 1, 1}).expand({-1, 1, 4})).squeeze(1);
  auto xyzw = torch::cat({wxyz.index({Slice(), Slice(1, 4)}), wxyz.index({Slice(), Slice(0, 1)})}, -1);
  xyzw = torch::where(xyzw.index({Slice(), Slice(3, 4)}) < 0, -xyzw, xyzw);
  batch.push_back(4);
  return xyzw.reshape(batch);
}

torch::Tensor quat_slerp(const torch::Tensor& q0_in, const torch::Tensor& q1_in, double t) {
  auto q0 = q0_in.to(torch::kFloat64);
  auto q1 = q1_in.to(torch::kFloat64);
  auto dot = (q0 * q1).sum(-1, true);
  q1 = torch::where(dot < 0, -q1, q1);  // shortest path
  dot = dot.abs().clamp_max(1.0);
  auto theta = torch::acos(dot);
  auto sin_theta = torch::sin(theta);
  auto near = sin_theta < 1e-8;
  auto w0 =
      torch::where(near, torch::full_like(dot, 1.0 - t), torch::sin((1.0 - t) * theta) / sin_theta.clamp_min(1e-12));
  auto w1 = torch::where(near, torch::full_like(dot, t), torch::sin(t * theta) / sin_theta.clamp_min(1e-12));
  auto q = w0 * q0 + w1 * q1;
  q = q / q.norm(2, -1, true).clamp_min(1e-12);
  return q.to(q0_in.scalar_type());
}

torch::Tensor quat_multiply(const torch::Tensor& a, const torch::Tensor& b) {
  auto ax = a.select(-1, 0), ay = a.select(-1, 1), az = a.select(-1, 2), aw = a.select(-1, 3);
  auto bx = b.select(-1, 0), by = b.select(-1, 1), bz = b.select(-1, 2), bw = b.select(-1, 3);
  return torch::stack({aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                       aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz},
                      -1);
}

torch::Tensor normalize_quat(const torch::Tensor& q, double eps) {
  auto q32 = q.to(torch::kFloat32);
  return (q32 / q32.norm(2, -1, true).clamp_min(eps)).to(q.scalar_type());
}

}  // namespace uplvsm::geometry
