// The perceptual training loss of LVSM / UP-LVSM (official loss.py `PerceptualLoss`): a frozen VGG19 whose
// max-pools are 2x2 average pools, fed 255*img minus the ImageNet mean (no std), compared at relu1_2, relu2_2,
// relu3_2, relu4_2 and relu5_2 with the LVSM layer weights:
//   loss = (L1(x) + L1(f1)/2.6 + L1(f2)/4.8 + L1(f3)/3.7 + L1(f4)/5.6 + 10 L1(f5)/1.5) / 255,  L1 = mean |a - b|.
// Weights: a torchvision-format VGG19 file (`features.N.*`), e.g. the one `uplvsm convert` extracts from an official
// checkpoint (`<output>.vgg19.safetensors`). The input is prepared for the weights given: the official MatConvNet
// weights see 255*img - mean, torchvision's own vgg19() weights see (img - mean) / std on [0, 1]; the pixel term is
// the official one either way. The divisors were tuned on the MatConvNet weights, so with torchvision's the five
// feature terms weigh differently from the paper's loss.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/backbones/vgg_features.h"
#include "uplvsm/core/config.h"

namespace uplvsm::train {

// What input a VGG19 weight file was trained on. Auto: read it from the file (the marker `uplvsm convert` writes).
enum class VggInput { Auto, MatConvNet, TorchVision };
VggInput parse_vgg_input(const std::string& name);  // "auto", "matconvnet", "torchvision"
std::string to_string(VggInput input);
// The safetensors metadata key (value "matconvnet" or "torchvision") that names a file's VggInput.
inline constexpr const char* kVggInputMetadataKey = "vgg19_input";

struct PerceptualLossImpl : torch::nn::Module {
  explicit PerceptualLossImpl(VggInput input = VggInput::MatConvNet);

  // MatConvNet: 255 * img - ImageNet mean (123.68, 116.779, 103.939), as the official _preprocess_images.
  // TorchVision: (img - (0.485, 0.456, 0.406)) / (0.229, 0.224, 0.225), as torchvision's VGG19_Weights transforms.
  torch::Tensor preprocess(const torch::Tensor& images01) const;
  // The five compared activations of a preprocessed [N, 3, H, W] batch.
  std::vector<torch::Tensor> features(const torch::Tensor& preprocessed);
  // The per-term errors [6] (pixel term, then the five layers), each already divided by its weight and by 255.
  torch::Tensor terms(const torch::Tensor& pred, const torch::Tensor& target);
  // Scalar loss of [..., 3, H, W] predictions against targets in [0, 1]; gradients flow into `pred` only.
  torch::Tensor forward(const torch::Tensor& pred, const torch::Tensor& target);

  backbones::VggFeatures vgg{nullptr};
  VggInput input;  // never Auto
};
TORCH_MODULE(PerceptualLoss);

// Layer index after each compared slice: features[0:4], [4:9], [9:14], [14:23], [23:32].
const std::vector<int64_t>& perceptual_slice_ends();
// Divisors of the six L1 terms before the common /255: 1, 2.6, 4.8, 3.7, 5.6, 1.5/10.
const std::vector<double>& perceptual_term_divisors();

// The input preparation for the weights in `path`: the file's marker, else `requested`. A file without a marker
// (torchvision's .pth, or a file converted before the marker existed) needs `requested`: the two kinds hold the same
// tensors under the same names and cannot be told apart reliably, so Auto is refused with an error naming the choice.
// A marker that contradicts `requested` is an error too.
VggInput resolve_vgg_input(const std::string& path, VggInput requested);
// A frozen, eval-mode perceptual loss with VGG19 weights from `path` (errors name the file and key).
PerceptualLoss load_perceptual_loss(const std::string& path, VggInput requested = VggInput::Auto);
// Refuses a run whose loss asks for the perceptual term without VGG19 weights (the official always trains with it;
// there is no silent MSE-only fallback): an error naming --vgg19, `uplvsm convert` (which writes them from an
// authors' checkpoint) and the explicit opt-out.
void require_perceptual_weights(const Config& config, const std::string& weights_path);
// What a run with training.perceptual_loss_weight = `weight` uses: the loss on `device` from `weights_path`, or null
// (MSE only) when the weight is 0 (a warning names an unused file). A weight above 0 without a file is an error.
PerceptualLoss perceptual_loss_for(double weight, const std::string& weights_path, torch::Device device,
                                   VggInput requested = VggInput::Auto);

}  // namespace uplvsm::train
