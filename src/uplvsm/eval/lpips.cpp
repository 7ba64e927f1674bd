#include "uplvsm/eval/lpips.h"

#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/pretrained_weights.h"

namespace uplvsm::eval {

LpipsNet parse_lpips_net(const std::string& name) {
  if (name == "vgg") return LpipsNet::Vgg;
  if (name == "alex") return LpipsNet::Alex;
  throw std::runtime_error(fmt::format("LPIPS network '{}': expected 'vgg' or 'alex'", name));
}

LpipsImpl::LpipsImpl(LpipsNet n) : net(n) {
  const bool vgg = n == LpipsNet::Vgg;
  backbone =
      register_module("net", backbones::VggFeatures(vgg ? backbones::Backbone::Vgg16 : backbones::Backbone::AlexNet));
  // Official pretrained_networks.py slicing: relu1_2..relu5_3 for vgg16, relu1..relu5 for alexnet.
  slice_ends = vgg ? std::vector<int64_t>{4, 9, 16, 23, 30} : std::vector<int64_t>{2, 5, 8, 10, 12};
  const std::vector<int64_t> channels =
      vgg ? std::vector<int64_t>{64, 128, 256, 512, 512} : std::vector<int64_t>{64, 192, 384, 256, 256};
  for (size_t k = 0; k < channels.size(); ++k)
    lin.push_back(register_buffer(fmt::format("lin{}", k), torch::zeros({1, channels[k], 1, 1})));
}

torch::Tensor LpipsImpl::scale_input(const torch::Tensor& images01) const {
  auto opts = images01.options();
  auto shift = torch::tensor({-.030, -.088, -.188}, opts).view({1, 3, 1, 1});
  auto scale = torch::tensor({.458, .448, .450}, opts).view({1, 3, 1, 1});
  return (2 * images01 - 1 - shift) / scale;
}

std::vector<torch::Tensor> LpipsImpl::features(const torch::Tensor& scaled) {
  std::vector<torch::Tensor> out;
  auto x = scaled;
  int64_t begin = 0;
  for (int64_t end : slice_ends) {
    x = backbone->run(x, begin, end);
    out.push_back(x);
    begin = end;
  }
  return out;
}

torch::Tensor LpipsImpl::per_layer(const torch::Tensor& in0, const torch::Tensor& in1, bool weighted) {
  TORCH_CHECK(in0.sizes() == in1.sizes() && in0.dim() == 4 && in0.size(1) == 3,
              "LPIPS: expected two [N, 3, H, W] "
              "batches of the same shape, got ",
              in0.sizes(), " and ", in1.sizes());
  auto f0 = features(scale_input(in0)), f1 = features(scale_input(in1));
  auto unit = [](const torch::Tensor& f) { return f / (f.pow(2).sum(1, true).sqrt() + 1e-10); };
  std::vector<torch::Tensor> terms;
  for (size_t k = 0; k < f0.size(); ++k) {
    auto d = (unit(f0[k]) - unit(f1[k])).pow(2);
    auto weighted_d = weighted ? (d * lin[k]).sum(1) : d.sum(1);
    terms.push_back(weighted_d.mean({1, 2}));
  }
  return torch::stack(terms, 1);
}

torch::Tensor LpipsImpl::forward(const torch::Tensor& in0, const torch::Tensor& in1) {
  auto lead = in0.sizes().slice(0, in0.dim() - 3).vec();
  auto flat0 = in0.reshape({-1, 3, in0.size(-2), in0.size(-1)});
  auto flat1 = in1.reshape({-1, 3, in1.size(-2), in1.size(-1)});
  return per_layer(flat0, flat1).sum(1).reshape(lead);
}

Lpips load_lpips(LpipsNet net, const std::string& backbone_path, const std::string& lin_path) {
  Lpips lpips(net);
  backbones::load_backbone(*lpips->backbone, backbone_path);
  auto weights = io::read_weight_file(lin_path);
  torch::NoGradGuard no_grad;
  for (size_t k = 0; k < lpips->lin.size(); ++k) {
    const std::string official = fmt::format("lin{}.model.1.weight", k), plain = fmt::format("lin{}", k);
    auto it = weights.count(official) ? weights.find(official) : weights.find(plain);
    if (it == weights.end())
      throw std::runtime_error(fmt::format("{}: LPIPS lin weights lack '{}' (or '{}')", lin_path, official, plain));
    if (it->second.sizes() != lpips->lin[k].sizes())
      throw std::runtime_error(fmt::format("{}: '{}' has shape [{}], expected [{}] for the {} network", lin_path,
                                           it->first, fmt::join(it->second.sizes(), ", "),
                                           fmt::join(lpips->lin[k].sizes(), ", "),
                                           net == LpipsNet::Vgg ? "vgg" : "alex"));
    lpips->lin[k].copy_(it->second.to(torch::kFloat32));
  }
  lpips->eval();
  return lpips;
}

}  // namespace uplvsm::eval
