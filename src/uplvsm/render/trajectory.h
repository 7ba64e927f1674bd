// Camera trajectories in the 7-D pose space (t, q_xyzw): linear translation and shortest-path slerp between key
// poses, both ends included per segment, as the official render_video (nerfstudio get_interpolated_poses_many).
#pragma once
#include <torch/torch.h>

namespace uplvsm::render {

// keys [K, 7] -> [(K - 1) * frames_per_segment, 7]; each segment samples t = linspace(0, 1, frames_per_segment).
torch::Tensor interpolate_poses(const torch::Tensor& keys, int64_t frames_per_segment);

// Same for intrinsics [K, 4] (linear), matching interpolate_poses' frame layout.
torch::Tensor interpolate_intrinsics(const torch::Tensor& keys, int64_t frames_per_segment);

}  // namespace uplvsm::render
