// The perceptual training loss of LVSM / UP-LVSM (official loss.py `PerceptualLoss`): a frozen VGG19 whose
// max-pools are 2x2 average pools, fed 255*img minus the ImageNet mean (no std), compared at relu1_2, relu2_2,
// relu3_2, relu4_2 and relu5_2 with the LVSM layer weights:
//   loss = (L1(x) + L1(f1)/2.6 + L1(f2)/4.8 + L1(f3)/3.7 + L1(f4)/5.6 + 10 L1(f5)/1.5) / 255,  L1 = mean |a - b|.
// Weights: a torchvision-format VGG19 file (`features.N.*`), e.g. the one `uplvsm convert` extracts from an official
// checkpoint (`<output>.vgg19.safetensors`).
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/model/vgg_features.h"

namespace uplvsm::train {

struct PerceptualLossImpl : torch::nn::Module {
  PerceptualLossImpl();

  // 255 * img - ImageNet mean (123.68, 116.779, 103.939), as the official _preprocess_images.
  torch::Tensor preprocess(const torch::Tensor& images01) const;
  // The five compared activations of a preprocessed [N, 3, H, W] batch.
  std::vector<torch::Tensor> features(const torch::Tensor& preprocessed);
  // The per-term errors [6] (pixel term, then the five layers), each already divided by its weight and by 255.
  torch::Tensor terms(const torch::Tensor& pred, const torch::Tensor& target);
  // Scalar loss of [..., 3, H, W] predictions against targets in [0, 1]; gradients flow into `pred` only.
  torch::Tensor forward(const torch::Tensor& pred, const torch::Tensor& target);

  model::VggFeatures vgg{nullptr};
};
TORCH_MODULE(PerceptualLoss);

// Layer index after each compared slice: features[0:4], [4:9], [9:14], [14:23], [23:32].
const std::vector<int64_t>& perceptual_slice_ends();
// Divisors of the six L1 terms before the common /255: 1, 2.6, 4.8, 3.7, 5.6, 1.5/10.
const std::vector<double>& perceptual_term_divisors();

// A frozen, eval-mode perceptual loss with VGG19 weights from `path` (errors name the file and key).
PerceptualLoss load_perceptual_loss(const std::string& path);
// What a run with training.perceptual_loss_weight = `weight` uses: the loss on `device` from `weights_path`, or null
// (MSE only) when the weight is 0 or no weights were given, with a warning naming what is unused or missing.
PerceptualLoss perceptual_loss_for(double weight, const std::string& weights_path, torch::Device device);

}  // namespace uplvsm::train
