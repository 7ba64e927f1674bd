#include "uplvsm/train/perceptual_loss.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <stdexcept>

#include "uplvsm/io/safetensors.h"

namespace uplvsm::train {

namespace {
constexpr std::array<const char*, 3> kVggInputNames{"auto", "matconvnet", "torchvision"};

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The marker in a safetensors file's metadata, or Auto (no marker, or not a safetensors file).
VggInput marked_vgg_input(const std::string& path) {
  if (!ends_with(path, ".safetensors")) return VggInput::Auto;
  std::map<std::string, std::string> metadata;
  io::read_safetensors_header(path, &metadata);
  const auto it = metadata.find(kVggInputMetadataKey);
  if (it == metadata.end()) return VggInput::Auto;
  const auto marked = parse_vgg_input(it->second);
  if (marked == VggInput::Auto)
    throw std::runtime_error(
        fmt::format("{}: metadata {} must be 'matconvnet' or 'torchvision'", path, kVggInputMetadataKey));
  return marked;
}
}  // namespace

VggInput parse_vgg_input(const std::string& name) {
  for (size_t i = 0; i < kVggInputNames.size(); ++i)
    if (name == kVggInputNames[i]) return static_cast<VggInput>(i);
  throw std::runtime_error("VGG19 input must be 'auto', 'matconvnet' or 'torchvision', got '" + name + "'");
}

std::string to_string(VggInput input) { return kVggInputNames.at(static_cast<size_t>(input)); }

const std::vector<int64_t>& perceptual_slice_ends() {
  static const std::vector<int64_t> ends = {4, 9, 14, 23, 32};
  return ends;
}

const std::vector<double>& perceptual_term_divisors() {
  static const std::vector<double> divisors = {1.0, 2.6, 4.8, 3.7, 5.6, 1.5 / 10.0};
  return divisors;
}

PerceptualLossImpl::PerceptualLossImpl(VggInput input_kind) : input(input_kind) {
  TORCH_CHECK(input != VggInput::Auto, "PerceptualLoss: the VGG19 input preparation must be resolved");
  vgg = register_module("vgg", backbones::VggFeatures(backbones::Backbone::Vgg19, /*avg_pool=*/true));
  for (auto& p : parameters()) p.set_requires_grad(false);
  eval();
}

torch::Tensor PerceptualLossImpl::preprocess(const torch::Tensor& images01) const {
  // An fp32 (or fp64) mean like the official buffer, so a bf16 render is promoted rather than the mean rounded.
  const auto options =
      images01.options().dtype(images01.scalar_type() == torch::kDouble ? torch::kDouble : torch::kFloat);
  if (input == VggInput::TorchVision) {
    auto mean = torch::tensor({0.485, 0.456, 0.406}, options).view({1, 3, 1, 1});
    auto stdev = torch::tensor({0.229, 0.224, 0.225}, options).view({1, 3, 1, 1});
    return (images01 - mean) / stdev;
  }
  auto mean = torch::tensor({123.68, 116.779, 103.939}, options).view({1, 3, 1, 1});
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
  auto pred01 = pred.reshape({-1, 3, pred.size(-2), pred.size(-1)});
  auto target01 = target.reshape({-1, 3, target.size(-2), target.size(-1)}).detach();
  auto p = preprocess(pred01), t = preprocess(target01);
  auto fp = features(p), ft = features(t);
  const auto& div = perceptual_term_divisors();
  // The pixel term on the official 0..255 scale (the mean cancels), whatever the VGG's input preparation.
  auto pixel = input == VggInput::MatConvNet ? (p - t).abs().mean() : (pred01 - target01).abs().mean() * 255.0;
  std::vector<torch::Tensor> out = {pixel / div[0]};
  for (size_t k = 0; k < fp.size(); ++k) out.push_back((fp[k] - ft[k]).abs().mean() / div[k + 1]);
  return torch::stack(out) / 255.0;
}

torch::Tensor PerceptualLossImpl::forward(const torch::Tensor& pred, const torch::Tensor& target) {
  return terms(pred, target).sum();
}

VggInput resolve_vgg_input(const std::string& path, VggInput requested) {
  const auto marked = marked_vgg_input(path);
  if (marked != VggInput::Auto && requested != VggInput::Auto && marked != requested)
    throw std::runtime_error(
        fmt::format("{}: these VGG19 weights are marked as taking {} input, not {} (--vgg19-input)", path,
                    to_string(marked), to_string(requested)));
  if (marked != VggInput::Auto) return marked;
  if (requested != VggInput::Auto) return requested;
  throw std::runtime_error(fmt::format(
      "{}: cannot tell which input these VGG19 weights expect; pass --vgg19-input torchvision for torchvision's "
      "vgg19() weights ([0, 1] normalised by the ImageNet mean and std) or --vgg19-input matconvnet for the official "
      "checkpoint's (255 x image - mean); `uplvsm convert` of an official checkpoint writes a file marked as such",
      path));
}

PerceptualLoss load_perceptual_loss(const std::string& path, VggInput requested) {
  PerceptualLoss loss(resolve_vgg_input(path, requested));
  backbones::load_backbone(*loss->vgg, path);
  loss->eval();
  return loss;
}

void require_perceptual_weights(const Config& config, const std::string& weights_path) {
  const double weight = config.training.perceptual_loss_weight;
  if (weight <= 0 || !weights_path.empty()) return;
  throw std::runtime_error(fmt::format(
      "config {}: training.perceptual_loss_weight is {:g} but no VGG19 weights were given. Give them with --vgg19 "
      "FILE (`uplvsm convert --input uplvsm_x224.pt --output model.safetensors` writes model.vgg19.safetensors "
      "from an authors' checkpoint), or train without the perceptual loss, explicitly: "
      "--set training.perceptual_loss_weight=0",
      config.name, weight));
}

PerceptualLoss perceptual_loss_for(double weight, const std::string& weights_path, torch::Device device,
                                   VggInput requested) {
  if (weight <= 0) {
    if (!weights_path.empty()) spdlog::warn("{} not used: training.perceptual_loss_weight is 0", weights_path);
    return nullptr;
  }
  if (weights_path.empty())
    throw std::runtime_error(
        fmt::format("training.perceptual_loss_weight is {:g} but no VGG19 weights were given (--vgg19 FILE)", weight));
  auto loss = load_perceptual_loss(weights_path, requested);
  loss->to(device);
  spdlog::info("perceptual loss: VGG19 from {} ({} input), weight {}", weights_path, to_string(loss->input), weight);
  return loss;
}

}  // namespace uplvsm::train
