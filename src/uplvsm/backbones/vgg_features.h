// torchvision's `features` stacks of AlexNet, VGG16 and VGG19 with torchvision's module indices, so weight files
// with `features.N.weight/bias` names (torchvision .pth, our safetensors, the official checkpoints' perceptual-loss
// VGG19 after `uplvsm convert`) load as they are. Frozen backbones of LPIPS (eval/) and the perceptual loss (train/).
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/io/state_dict.h"

namespace uplvsm::backbones {

enum class Backbone { AlexNet, Vgg16, Vgg19 };

struct VggFeaturesImpl : torch::nn::Module {
  // avg_pool: max-pools replaced by 2x2 average pools (the LVSM / UP-LVSM perceptual loss).
  explicit VggFeaturesImpl(Backbone backbone, bool avg_pool = false);
  // Runs layers [begin, end) of `features` on x.
  torch::Tensor run(torch::Tensor x, int64_t begin, int64_t end);

  enum class Layer { Conv, Relu, MaxPool, AvgPool };
  Backbone backbone;
  std::vector<Layer> layers;
  torch::nn::ModuleList features{nullptr};
};
TORCH_MODULE(VggFeatures);

// Loads `features.*` tensors of a weight file (safetensors / .pth / .pt; other keys such as `classifier.*` are
// ignored and counted) strictly into the backbone, freezes it and puts it in eval mode.
io::LoadReport load_backbone(VggFeaturesImpl& backbone, const std::string& path);

}  // namespace uplvsm::backbones
