#include "uplvsm/train/perceptual_loss.h"

#include <spdlog/spdlog.h>

namespace uplvsm::train {

const std::vector<int64_t>& perceptual_slice_ends() {
  static const std::vector<int64_t> ends = {4, 9, 14, 23, 32};
  return ends;
}

const std::vector<double>& perceptual_term_divisors() {
  static const std::vector<double> divisors = {1.0, 2.6, 4.8, 3.7, 5.6, 1.5 / 10.0};
  return divisors;
}

PerceptualLossImpl::PerceptualLossImpl() {
  vgg = register_module("vgg", model::VggFeatures(model::Backbone::Vgg19, /*avg_pool=*/true));
  for (auto& p : parameters()) p.set_requires_grad(false);
  eval();
}

torch::Tensor PerceptualLossImpl::preprocess(const torch::Tensor& images01) const {
  // An fp32 (or fp64) mean like the official buffer, so a bf16 render is promoted rather than the mean rounded.
  const auto dtype = images01.scalar_type() == torch::kDouble ? torch::kDouble : torch::kFloat;
  auto mean = torch::tensor({123.68, 116.779, 103.939}, images01.options().dtype(dtype)).view({1, 3, 1, 1});
  return images01 * 255.0 - mean;
}

std::vector<torch::Tensor> PerceptualLossImpl::features(const torch::Tensor& x) {
  std::vector<torch::Tensor> out;
  auto h = x;
  int64_t begin = 0;
  for (int64_t end : perceptual_slice_ends()) {
    h = vgg->run(h, begin, end);
    out.push_back(h);
    begin = end;
  }
  return out;
}

torch::Tensor PerceptualLossImpl::terms(const torch::Tensor& pred, const torch::Tensor& target) {
  TORCH_CHECK(pred.sizes() == target.sizes() && pred.dim() >= 3 && pred.size(-3) == 3,
              "perceptual loss: expected prediction and target of the same [..., 3, H, W] shape, got ", pred.sizes(),
              " and ", target.sizes());
  auto p = preprocess(pred.reshape({-1, 3, pred.size(-2), pred.size(-1)}));
  auto t = preprocess(target.reshape({-1, 3, target.size(-2), target.size(-1)}).detach());
  auto fp = features(p), ft = features(t);
  const auto& div = perceptual_term_divisors();
  std::vector<torch::Tensor> out = {(p - t).abs().mean() / div[0]};
  for (size_t k = 0; k < fp.size(); ++k) out.push_back((fp[k] - ft[k]).abs().mean() / div[k + 1]);
  return torch::stack(out) / 255.0;
}

torch::Tensor PerceptualLossImpl::forward(const torch::Tensor& pred, const torch::Tensor& target) {
  return terms(pred, target).sum();
}

PerceptualLoss load_perceptual_loss(const std::string& path) {
  PerceptualLoss loss;
  model::load_backbone(*loss->vgg, path);
  loss->eval();
  return loss;
}

PerceptualLoss perceptual_loss_for(double weight, const std::string& weights_path, torch::Device device) {
  if (weight <= 0) {
    if (!weights_path.empty()) spdlog::warn("{} not used: training.perceptual_loss_weight is 0", weights_path);
    return nullptr;
  }
  if (weights_path.empty()) {
    spdlog::warn(
        "training.perceptual_loss_weight is {} but no VGG19 weights were given (--vgg19 FILE): training "
        "with MSE only",
        weight);
    return nullptr;
  }
  auto loss = load_perceptual_loss(weights_path);
  loss->to(device);
  spdlog::info("perceptual loss: VGG19 from {}, weight {}", weights_path, weight);
  return loss;
}

}  // namespace uplvsm::train
