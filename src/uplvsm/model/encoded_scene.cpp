#include "uplvsm/model/encoded_scene.h"

#include <algorithm>
#include <vector>

namespace uplvsm::model {

EncodedScene encode_scene(UPLVSMImpl& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                          bool estimate_input_poses) {
  TORCH_CHECK(images.dim() == 4 && images.size(0) == 2 && images.size(1) == 3,
              "encode_scene: a scene is two views [2, 3, H, W], got ", images.sizes());
  torch::NoGradGuard no_grad;
  const auto device = net.n_light_field_latent.device();
  auto inputs = images.unsqueeze(0).to(device);
  auto k = fxfycxcy.unsqueeze(0).to(device);
  EncodedScene scene;
  scene.height = images.size(2);
  scene.width = images.size(3);
  if (!estimate_input_poses) {
    scene.latents = net.encode_scene(inputs, k);
    return scene;
  }
  auto encoded = net.encode_with_input_poses(inputs, k);
  scene.latents = encoded.latents;
  scene.input_poses = encoded.input_poses[0];
  return scene;
}

torch::Tensor render_latent_poses(UPLVSMImpl& net, const EncodedScene& scene, const torch::Tensor& poses,
                                  const torch::Tensor& intrinsics, int64_t chunk) {
  TORCH_CHECK(poses.dim() == 2 && poses.size(1) == 7 && intrinsics.dim() == 2 && intrinsics.size(0) == poses.size(0),
              "render: expected poses [F, 7] and intrinsics [F, 4], got ", poses.sizes(), " and ", intrinsics.sizes());
  torch::NoGradGuard no_grad;
  const auto device = scene.latents.device();
  const int64_t frames = poses.size(0), step = chunk > 0 ? chunk : std::max<int64_t>(frames, 1);
  std::vector<torch::Tensor> out;
  for (int64_t s = 0; s < frames; s += step) {
    const int64_t n = std::min(step, frames - s);
    out.push_back(net.render_views(scene.latents, poses.slice(0, s, s + n).unsqueeze(0).to(device),
                                   intrinsics.slice(0, s, s + n).unsqueeze(0).to(device), scene.height, scene.width)[0]
                      .to(torch::kCPU, torch::kFloat32));
  }
  return out.size() == 1 ? out.front() : torch::cat(out);
}

torch::Tensor mapper_conditioning(const EncodedScene& scene) {
  TORCH_CHECK(scene.input_poses.defined(), "mapper_conditioning: the scene was encoded without its inputs' poses");
  return scene_conditioning(scene.input_poses.unsqueeze(0).to(torch::kFloat32));
}

torch::Tensor latent_poses_of_cameras(UPLVSMImpl& net, const EncodedScene& scene, const torch::Tensor& real_poses) {
  TORCH_CHECK(net.pose_mapper, "this model has no camera mapper: render latent poses");
  TORCH_CHECK(real_poses.dim() == 2 && real_poses.size(1) == 7, "camera poses must be [F, 7], got ",
              real_poses.sizes());
  torch::NoGradGuard no_grad;
  auto p = real_poses.to(scene.latents.device(), torch::kFloat32).unsqueeze(0);
  return net.pose_mapper(p, net.pose_mapper->reads_scene() ? mapper_conditioning(scene) : torch::Tensor())[0];
}

}  // namespace uplvsm::model
