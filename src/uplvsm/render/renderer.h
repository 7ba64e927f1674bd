// Novel-view videos from two input images, decoded in chunks of views, written as PNG frames, an MP4 and a GIF.
// - render_interpolation: unposed; the Latent Plücker Learner estimates the inputs' latent poses, which are
//   interpolated (no camera control needed); it and render_latent_path decode an encoded scene
//   (model/encoded_scene.h).
// - render_camera_path: real cameras in camera-control units (render/trajectory.h), placed by the model's camera
//   control: UP-LVSM's pose mapper, or the posed models' world cameras (they need the inputs' c2w).
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::render {

struct InterpolationVideo {
  torch::Tensor frames;     // [F, 3, H, W] in [0, 1], CPU
  torch::Tensor poses;      // [F, 7] latent poses
  torch::Tensor key_poses;  // [2, 7] the estimator's latent poses of the two inputs
};

// images [2, 3, H, W] in [0, 1], fxfycxcy [2, 4] pixels. Runs without gradients on the model's device.
InterpolationVideo render_interpolation(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                        int64_t num_frames, int64_t chunk = 4);

// Latent poses [F, 7] given directly (a camera path recorded in latent units), intrinsics [F, 4] pixels; images
// [2, 3, H, W], fxfycxcy [2, 4]. UP-LVSM only. Returns frames [F, 3, H, W] on the CPU.
torch::Tensor render_latent_path(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                 const torch::Tensor& poses, const torch::Tensor& intrinsics, int64_t chunk = 4);

// poses [F, 7] camera-control units, fxfycxcy [F, 4] pixels of the inputs' size; inputs: images [2, 3, H, W],
// fxfycxcy [2, 4], c2w [2, 4, 4] (needed by the posed models; may be undefined for UP-LVSM with a mapper).
// Returns frames [F, 3, H, W] on the CPU.
torch::Tensor render_camera_path(model::NovelViewModel& net, const data::SceneViews& inputs, const torch::Tensor& poses,
                                 const torch::Tensor& fxfycxcy, int64_t chunk = 4);

// The device a model's parameters live on.
torch::Device model_device(const torch::nn::Module& net);

// Frames [F, 3, H, W] beside the inputs [2, 3, H, W]: [input 0 | input 1 | frame] per frame.
torch::Tensor side_by_side(const torch::Tensor& inputs, const torch::Tensor& frames);

struct VideoFiles {
  std::string frames_dir, mp4, gif;  // mp4 empty when no encoder is available
};
// Writes <dir>/frames/frame_XXXX.png, <dir>/<name>.mp4 and <dir>/<name>.gif.
VideoFiles write_video(const std::string& dir, const std::string& name, const torch::Tensor& frames, double fps);

}  // namespace uplvsm::render
