// Cameras: intrinsics (pixels / normalised), c2w <-> w2c, the 7-D pose encoding (translation then scalar-last
// quaternion, official `absT_quaR`), first-view-canonical normalisation and the official scene-scale normalisation.
// Conventions: OpenCV axes (x right, y down, z forward); c2w = [R | t] maps camera to world; intrinsics are
// (fx, fy, cx, cy) in pixels unless a name says "normalised".
#pragma once
#include <torch/torch.h>

namespace uplvsm::geometry {

// [..., 7] (tx, ty, tz, qx, qy, qz, qw) -> [..., 4, 4] c2w (official pose_encoding_to_c2w).
torch::Tensor pose_encoding_to_c2w(const torch::Tensor& enc);
// [..., 4, 4] or [..., 3, 4] c2w -> [..., 7] with qw >= 0 (official c2w_to_pose_encoding).
torch::Tensor c2w_to_pose_encoding(const torch::Tensor& c2w);

// Inverse of a rigid [..., 4, 4] transform via R^T (exact for rotations; use torch::linalg_inv for general ones).
torch::Tensor invert_rigid(const torch::Tensor& T);
// [..., 3, 4] -> [..., 4, 4] with the row [0, 0, 0, 1].
torch::Tensor pad_to_4x4(const torch::Tensor& T34);
torch::Tensor identity_c2w(at::IntArrayRef batch, const torch::TensorOptions& options);

// Left-multiply every camera by inv(c2w of view 0) so view 0 becomes the identity (paper: first view canonical).
// c2w: [..., V, 4, 4].
torch::Tensor normalize_to_first_view(const torch::Tensor& c2w);

// Official `preprocess_poses` (per sample over its views [V, 4, 4]): re-centre on the mean camera centre with the
// mean viewing direction as z, then scale translations so max |t| = 1 / scale_factor (1.35 in the official config).
torch::Tensor official_scene_normalize(const torch::Tensor& c2w, double scale_factor = 1.35);
// The same similarity transform, computed from `reference` [R, 4, 4] and applied to c2w [V, 4, 4] (so cameras added
// later, e.g. a video path, do not move the frame).
torch::Tensor official_scene_normalize(const torch::Tensor& c2w, const torch::Tensor& reference,
                                       double scale_factor = 1.35);

// (fx, fy, cx, cy) normalised by (W, H) <-> pixels; [..., 4].
torch::Tensor intrinsics_to_pixels(const torch::Tensor& normalized, int64_t height, int64_t width);
torch::Tensor intrinsics_to_normalized(const torch::Tensor& pixels, int64_t height, int64_t width);
// [..., 4] -> [..., 3, 3] K matrix.
torch::Tensor intrinsics_matrix(const torch::Tensor& fxfycxcy);

}  // namespace uplvsm::geometry
