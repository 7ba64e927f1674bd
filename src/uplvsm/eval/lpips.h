// LPIPS v0.1 (Zhang et al. 2018) exactly as `lpips.LPIPS(net=..., version='0.1')(x, y, normalize=True)` computes
// it: [0,1] -> [-1,1] -> ScalingLayer -> torchvision backbone (VGG16 default, AlexNet optional) -> 5 activations,
// each unit-normalised over channels (+1e-10), squared difference, the official non-negative 1x1 `lin` weights,
// spatial mean, summed. Backbone weights come from a torchvision-format file the user gives (`features.N.*`); the
// lin weights from the official lpips `.pth` (legacy torch format, read natively) or a safetensors copy.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/backbones/vgg_features.h"

namespace uplvsm::eval {

enum class LpipsNet { Alex, Vgg };
LpipsNet parse_lpips_net(const std::string& name);  // "vgg" | "alex"

struct LpipsImpl : torch::nn::Module {
  explicit LpipsImpl(LpipsNet net);

  // ScalingLayer(2x - 1) of [N, 3, H, W] images in [0, 1].
  torch::Tensor scale_input(const torch::Tensor& images01) const;
  // The 5 backbone activations of a scaled input.
  std::vector<torch::Tensor> features(const torch::Tensor& scaled);
  // Per-layer terms [N, 5] (retPerLayer); `weighted` false gives sum_c (f0n - f1n)^2 without the lin weights.
  torch::Tensor per_layer(const torch::Tensor& in0, const torch::Tensor& in1, bool weighted = true);
  // LPIPS of [..., 3, H, W] image pairs in [0, 1]: float [...].
  torch::Tensor forward(const torch::Tensor& in0, const torch::Tensor& in1);

  LpipsNet net;
  backbones::VggFeatures backbone{nullptr};
  std::vector<int64_t> slice_ends;  // layer index after each of the 5 slices
  std::vector<torch::Tensor> lin;   // [1, C_k, 1, 1] buffers lin0..lin4
};
TORCH_MODULE(Lpips);

// A ready LPIPS (eval mode, frozen) from a backbone file and a lin file. Lin keys: `lin{k}.model.1.weight` (official
// .pth) or `lin{k}`. Errors name the file and the key.
Lpips load_lpips(LpipsNet net, const std::string& backbone_path, const std::string& lin_path);

}  // namespace uplvsm::eval
