#include "uplvsm/geometry/camera.h"

#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::geometry {

using torch::indexing::Ellipsis;
using torch::indexing::Slice;

torch::Tensor pad_to_4x4(const torch::Tensor& T34) {
  TORCH_CHECK(T34.size(-2) == 3 && T34.size(-1) == 4, "pad_to_4x4: expected [..., 3, 4], got ", T34.sizes());
  auto row = torch::zeros_like(T34.index({Ellipsis, Slice(0, 1), Slice()}));
  row.index_put_({Ellipsis, 0, 3}, 1.0);
  return torch::cat({T34, row}, -2);
}

torch::Tensor identity_c2w(at::IntArrayRef batch, const torch::TensorOptions& options) {
  auto shape = batch.vec();
  shape.push_back(4);
  shape.push_back(4);
  return torch::eye(4, options).expand(shape).clone();
}

torch::Tensor pose_encoding_to_c2w(const torch::Tensor& enc) {
  TORCH_CHECK(enc.size(-1) == 7, "pose_encoding_to_c2w: expected [..., 7] (t, q_xyzw), got ", enc.sizes());
  auto t = enc.index({Ellipsis, Slice(0, 3)});
  auto R = quat_to_rotation(enc.index({Ellipsis, Slice(3, 7)}));
  return pad_to_4x4(torch::cat({R, t.unsqueeze(-1)}, -1));
}

torch::Tensor c2w_to_pose_encoding(const torch::Tensor& c2w) {
  auto R = c2w.index({Ellipsis, Slice(0, 3), Slice(0, 3)});
  auto t = c2w.index({Ellipsis, Slice(0, 3), 3});
  return torch::cat({t, rotation_to_quat(R)}, -1);
}

torch::Tensor invert_rigid(const torch::Tensor& T) {
  auto R = T.index({Ellipsis, Slice(0, 3), Slice(0, 3)});
  auto t = T.index({Ellipsis, Slice(0, 3), Slice(3, 4)});
  auto Rt = R.transpose(-1, -2);
  return pad_to_4x4(torch::cat({Rt, -torch::matmul(Rt, t)}, -1));
}

torch::Tensor normalize_to_first_view(const torch::Tensor& c2w) {
  auto first_inv = torch::linalg_inv(c2w.select(-3, 0).to(torch::kFloat64));
  return torch::matmul(first_inv.unsqueeze(-3), c2w.to(torch::kFloat64)).to(c2w.scalar_type());
}

torch::Tensor official_scene_normalize(const torch::Tensor& c2w_in, double scale_factor) {
  return official_scene_normalize(c2w_in, c2w_in, scale_factor);
}

torch::Tensor official_scene_normalize(const torch::Tensor& c2w_in, const torch::Tensor& reference_in,
                                       double scale_factor) {
  TORCH_CHECK(c2w_in.dim() == 3 && c2w_in.size(1) == 4 && c2w_in.size(2) == 4 && reference_in.dim() == 3 &&
                  reference_in.size(1) == 4 && reference_in.size(2) == 4,
              "official_scene_normalize: expected [V, 4, 4] cameras, got ", c2w_in.sizes(), " and reference ",
              reference_in.sizes());
  auto ref = reference_in.to(torch::kFloat64);
  auto centre = ref.index({Slice(), Slice(0, 3), 3}).mean(0);
  auto f = torch::nn::functional::normalize(ref.index({Slice(), Slice(0, 3), 2}).mean(0),
                                            torch::nn::functional::NormalizeFuncOptions().dim(0));
  auto dn = ref.index({Slice(), Slice(0, 3), 1}).mean(0);
  auto r = torch::nn::functional::normalize(torch::linalg_cross(dn, f, 0),
                                            torch::nn::functional::NormalizeFuncOptions().dim(0));
  dn = torch::nn::functional::normalize(torch::linalg_cross(f, r, 0),
                                        torch::nn::functional::NormalizeFuncOptions().dim(0));
  auto inv_frame = torch::linalg_inv(pad_to_4x4(torch::stack({r, dn, f, centre}, 1))).unsqueeze(0);
  auto ref_t = torch::matmul(inv_frame, ref).index({Slice(), Slice(0, 3), 3});
  auto scale = ref_t.abs().max().clamp_min(1e-12) * scale_factor;
  auto out = torch::matmul(inv_frame, c2w_in.to(torch::kFloat64));
  out.index_put_({Slice(), Slice(0, 3), 3}, out.index({Slice(), Slice(0, 3), 3}) / scale);
  return out.to(c2w_in.scalar_type());
}

torch::Tensor intrinsics_to_pixels(const torch::Tensor& n, int64_t height, int64_t width) {
  auto scale = torch::tensor({double(width), double(height), double(width), double(height)}, n.options());
  return n * scale;
}

torch::Tensor intrinsics_to_normalized(const torch::Tensor& p, int64_t height, int64_t width) {
  auto scale = torch::tensor({double(width), double(height), double(width), double(height)}, p.options());
  return p / scale;
}

torch::Tensor intrinsics_matrix(const torch::Tensor& k) {
  auto z = torch::zeros_like(k.select(-1, 0));
  auto o = torch::ones_like(z);
  return torch::stack({k.select(-1, 0), z, k.select(-1, 2), z, k.select(-1, 1), k.select(-1, 3), z, z, o}, -1)
      .reshape([&] {
        auto s = k.sizes().vec();
        s.back() = 3;
        s.push_back(3);
        return s;
      }());
}

}  // namespace uplvsm::geometry
