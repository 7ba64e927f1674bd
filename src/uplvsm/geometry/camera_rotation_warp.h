// What a camera rotated in place would see: a pure rotation is a homography (x' ~ K R^T K^-1 x), so an image can be
// re-rendered exactly for any small turn of its camera, except near the borders it turns away from. Training uses
// it as a self-supervised rotation signal (training.rotation_equivariance_weight): the latent pose of the warped
// image must be the original's turned by the known angle. No ground-truth camera is involved.
#pragma once
#include <torch/torch.h>

namespace uplvsm::geometry {

// Rotations [N, 3, 3] about the camera's own y axis (OpenCV axes: x right, y down, z forward) by `radians` [N]: a
// turn to the side.
torch::Tensor yaw_rotation(const torch::Tensor& radians);

// images [N, C, H, W] of cameras with pixel intrinsics fxfycxcy [N, 4] (pixel centres at +0.5), seen by the same
// cameras rotated in place: c2w' = c2w [rotation 0; 0 1], rotation [N, 3, 3]. Bilinear; zeros where the rotated
// camera sees beyond the original image.
torch::Tensor warp_to_rotated_camera(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                     const torch::Tensor& rotation);

// [N, 1, H, W] in {0, 1}: the pixels of the rotated cameras' H x W views that the original images cover (where
// warp_to_rotated_camera has data rather than its zero padding).
torch::Tensor pixels_kept_by_rotation(const torch::Tensor& fxfycxcy, int64_t height, int64_t width,
                                      const torch::Tensor& rotation);

// [N, 1, H, W] in {0, 1}: the pixels every yaw within ±max_radians keeps inside the image (the same band for any
// angle, so it says nothing about the angle a warped image was made with).
torch::Tensor yaw_safe_region(const torch::Tensor& fxfycxcy, int64_t height, int64_t width, double max_radians);

}  // namespace uplvsm::geometry
