// Novel-view video from two unposed input images: encode the scene, ask the Latent Plücker Learner for the latent
// poses of the input views themselves, interpolate between them, decode every frame (in chunks of views), and write
// PNG frames, an MP4 and a GIF.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/model/uplvsm.h"

namespace uplvsm::render {

struct InterpolationVideo {
  torch::Tensor frames;    // [F, 3, H, W] in [0, 1], CPU
  torch::Tensor poses;     // [F, 7] latent poses
  torch::Tensor key_poses; // [2, 7] the estimator's latent poses of the two inputs
};

// images [2, 3, H, W] in [0, 1], fxfycxcy [2, 4] pixels. Runs without gradients on the model's device.
InterpolationVideo render_interpolation(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                        int64_t num_frames, int64_t chunk = 4);

struct VideoFiles {
  std::string frames_dir, mp4, gif;  // mp4 empty when no encoder is available
};
// Writes <dir>/frames/frame_XXXX.png, <dir>/<name>.mp4 and <dir>/<name>.gif.
VideoFiles write_video(const std::string& dir, const std::string& name, const torch::Tensor& frames, double fps);

}  // namespace uplvsm::render
