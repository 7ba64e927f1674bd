// Wobble of a rendered camera path, measured on the picture's motion rather than on its pixels (issue 82). The
// earlier figure, RMS(r[t+1] - 2 r[t] + r[t-1]) / RMS(r[t+1] - r[t]), grew in proportion to how fast a steady picture
// moves and with finer texture, so a mapper that moved the camera further scored as shakier. Here the picture's
// motion between consecutive frames is estimated as an optical flow (Lucas-Kanade: a 9x9 window, four warped
// refinements, each followed by a weighted average of the flow over the window; bilinear sampling), in pixels per
// frame; a steady motion has a constant flow at any speed and texture, so the wobble is how much the flow changes
// from one frame to the next: W = RMS over frames and pixels of |u[t+1] - u[t]|, in pixels per frame², pixels weighted
// by how well their flow is determined (the smaller eigenvalue of the window's structure tensor: flat walls and
// straight edges cannot say where they move). A picture that jumps ±A pixels about a steady slide every other frame
// scores 4A. Given the ground truth along the same path, the truth's own change of motion (turns, parallax sweeping
// past a pixel) is subtracted: W = RMS |(u_r[t+1] - u_r[t]) - (u_g[t+1] - u_g[t])|, so a path that turns, or a render
// that lags or blurs steadily, scores 0; only motion the truth does not make remains.
#pragma once
#include <torch/torch.h>

namespace uplvsm::eval {

// The picture's motion between consecutive frames of [T >= 2, C, H, W] in [0, 1] (colour averaged): flow [T-1, 2, H,
// W] in pixels per frame (x right, y down: where a pixel of frame t is found in frame t+1) and each pixel's weight
// [T-1, 1, H, W] (>= 0; the frames' own scale), both float64, a border of kMotionBorder pixels to be ignored.
struct PictureMotion {
  torch::Tensor flow, weight;
};
inline constexpr int64_t kMotionBorder = 8;
PictureMotion picture_motion(const torch::Tensor& frames);

// W above, pixels per frame², of frames [T >= 3, C, H, W] (with `truth` of the same shape: relative to its motion);
// 0 where no pixel has texture to follow.
double temporal_wobble(const torch::Tensor& frames, const torch::Tensor& truth = {});
// The change of motion between consecutive steps [T-2, 2, h, w] of frames [T >= 3, C, H, W] and its weight
// [T-2, 1, h, w] (a step pair counts as well determined as its worse step; weights relative to their mean, so that two
// sequences combine): a truth's, computed once, serves every render scored against it.
struct MotionChange {
  torch::Tensor change, weight;
};
MotionChange motion_change(const torch::Tensor& frames);
double temporal_wobble(const torch::Tensor& frames, const MotionChange& truth);
// The picture's RMS speed along frames [T >= 2, C, H, W], pixels per frame (the same weights).
double picture_speed(const torch::Tensor& frames);

}  // namespace uplvsm::eval
