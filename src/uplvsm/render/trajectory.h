// Camera trajectories in the 7-D pose space (t, q_xyzw).
// - interpolate_poses: linear translation and shortest-path slerp between key poses, both ends included per
//   segment, as the official render_video (nerfstudio get_interpolated_poses_many).
// - Presets and camera-path files give *real* cameras in camera-control units (model/pose_mapper.h): relative to
//   the first input view (the canonical frame: OpenCV axes, x right, y down, z forward) with translations in units
//   of the input baseline. A camera mapper (or a posed variant) turns them into renders.
#pragma once
#include <torch/torch.h>

#include <string>

namespace uplvsm::render {

// keys [K, 7] -> [(K - 1) * frames_per_segment, 7]; each segment samples t = linspace(0, 1, frames_per_segment).
// Computed in float64 and returned in float32 (float64 for float64 keys), whatever the keys' precision (bf16 keys
// from an autocast forward give a smooth path, not one snapped to bf16 poses).
torch::Tensor interpolate_poses(const torch::Tensor& keys, int64_t frames_per_segment);

// Same for intrinsics [K, 4] (linear, same precision rule), matching interpolate_poses' frame layout.
torch::Tensor interpolate_intrinsics(const torch::Tensor& keys, int64_t frames_per_segment);

// A camera at `position` [3] looking at `target` [3], its y axis as close as possible to the first view's (down):
// pose [7] (float64).
torch::Tensor look_at_pose(const torch::Tensor& position, const torch::Tensor& target);

struct PresetOptions {
  double focus_distance = 2.0;  // the point orbited / looked at lies this far in front of the first view
  double radius = 0.5;          // orbit arc / spiral radius / dolly travel, in baselines
  double arc_degrees = 30.0;    // orbit: swing of +-arc/2 around the focus point
};

// Looping camera paths of `frames` poses [frames, 7] starting at the first input view:
//   orbit  — swings left/right on a circle around the focus point, always looking at it;
//   spiral — circles in the image plane (and a little forward) while looking at the focus point;
//   dolly  — moves forward and back along the viewing axis, looking straight ahead.
// Throws std::invalid_argument for an unknown name.
torch::Tensor camera_path_preset(const std::string& name, int64_t frames, const PresetOptions& options = {});

// The most frames a video may have (`--frames`, camera-path files): bounds what a file can make us render and hold.
inline constexpr int64_t kMaxVideoFrames = 100000;

// A user's camera path: JSON {"frames": [ {"pose": [tx, ty, tz, qx, qy, qz, qw]} or {"c2w": 4x4 or 3x4 rows},
// optional "fxfycxcy": [fx, fy, cx, cy] normalised by the image size ], "units": "baseline" | "latent"}. Returns
// poses [F, 7] (float64) and normalised intrinsics [F, 4] (undefined when no frame gives them; all or none must).
// "latent" poses (recorded in the viewer on a model without a camera mapper) go to the decoder as they are; they
// belong to the scene they were recorded on. Errors name the file, the frame and the field; more than
// kMaxVideoFrames frames is an error.
struct CameraPath {
  torch::Tensor poses;
  torch::Tensor fxfycxcy_normalized;
  bool latent = false;  // "units": "latent"
};
CameraPath read_camera_path(const std::string& path);

}  // namespace uplvsm::render
