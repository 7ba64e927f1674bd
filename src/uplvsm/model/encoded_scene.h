// One scene as rendering needs it, computed once: "encode once, estimate the inputs' poses, render any path". The
// renderer (render/renderer.h), the viewer (serve/viewer_model.h) and through the renderer the Python module all
// start from this: the scene latents of two unposed input views and the latent poses the estimator reads from them,
// then batches of latent poses, or of real cameras through the model's pose mapper, decoded into frames.
#pragma once
#include <torch/torch.h>

#include <cstdint>

#include "uplvsm/model/uplvsm.h"

namespace uplvsm::model {

struct EncodedScene {
  torch::Tensor latents;          // [1, L, d] scene latents on the model's device
  torch::Tensor input_poses;      // [2, 7] the estimator's latent poses of the inputs, on that device (or undefined)
  int64_t height = 0, width = 0;  // the inputs' size, every frame's
};

// images [2, 3, H, W] in [0, 1], fxfycxcy [2, 4] pixels, on any device (moved to the model's; their dtypes kept).
// Without gradients; estimate_input_poses false leaves input_poses undefined (the estimator does not run).
EncodedScene encode_scene(UPLVSMImpl& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                          bool estimate_input_poses = true);

// Latent poses [F, 7] and intrinsics [F, 4] (pixels), on any device in the dtype the decoder is to read (float32;
// a mapper's output under autocast as it comes) -> frames [F, 3, H, W] float32 on the CPU, `chunk` frames per
// decoder call (0: all at once). Without gradients.
torch::Tensor render_latent_poses(UPLVSMImpl& net, const EncodedScene& scene, const torch::Tensor& poses,
                                  const torch::Tensor& intrinsics, int64_t chunk = 0);

// Real cameras [F, 7] (camera-control units: relative to input 0, in input baselines) -> latent poses [F, 7] on the
// model's device (read as float32), through the model's pose mapper (an MLP mapper also reads the inputs' latent poses,
// which the scene must hold). An error without a mapper.
torch::Tensor latent_poses_of_cameras(UPLVSMImpl& net, const EncodedScene& scene, const torch::Tensor& real_poses);
// What an MLP mapper reads of the scene: [1, 14] float32, the inputs' latent poses.
torch::Tensor mapper_conditioning(const EncodedScene& scene);

}  // namespace uplvsm::model
