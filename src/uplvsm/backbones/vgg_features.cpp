#include "uplvsm/backbones/vgg_features.h"

#include <fmt/format.h>

#include "uplvsm/io/pretrained_weights.h"

namespace uplvsm::backbones {

namespace {
namespace nn = torch::nn;

struct ConvSpec {
  int64_t in, out, kernel, stride, padding;
};
}  // namespace

VggFeaturesImpl::VggFeaturesImpl(Backbone b, bool avg_pool) : backbone(b) {
  features = register_module("features", nn::ModuleList());
  const Layer pool = avg_pool ? Layer::AvgPool : Layer::MaxPool;
  auto add_conv = [&](ConvSpec s) {
    features->push_back(nn::Conv2d(nn::Conv2dOptions(s.in, s.out, s.kernel).stride(s.stride).padding(s.padding)));
    features->push_back(nn::ReLU());
    layers.push_back(Layer::Conv);
    layers.push_back(Layer::Relu);
  };
  auto add_pool = [&] {
    features->push_back(nn::Identity());  // placeholder keeps torchvision's indices; the pool runs functionally
    layers.push_back(pool);
  };
  if (b == Backbone::AlexNet) {
    add_conv({3, 64, 11, 4, 2});
    add_pool();
    add_conv({64, 192, 5, 1, 2});
    add_pool();
    add_conv({192, 384, 3, 1, 1});
    add_conv({384, 256, 3, 1, 1});
    add_conv({256, 256, 3, 1, 1});
    return;
  }
  const std::vector<int64_t> cfg16 = {64, 64, 0, 128, 128, 0, 256, 256, 256, 0, 512, 512, 512, 0, 512, 512, 512, 0};
  const std::vector<int64_t> cfg19 = {64,  64,  0,   128, 128, 0,   256, 256, 256, 256, 0,
                                      512, 512, 512, 512, 0,   512, 512, 512, 512, 0};
  int64_t in = 3;
  for (int64_t c : b == Backbone::Vgg16 ? cfg16 : cfg19) {
    if (c == 0) {
      add_pool();
    } else {
      add_conv({in, c, 3, 1, 1});
      in = c;
    }
  }
}

torch::Tensor VggFeaturesImpl::run(torch::Tensor x, int64_t begin, int64_t end) {
  TORCH_CHECK(0 <= begin && begin <= end && end <= int64_t(layers.size()), "VggFeatures: layers [", begin, ", ", end,
              ") out of range");
  for (int64_t i = begin; i < end; ++i) {
    switch (layers[size_t(i)]) {
      case Layer::Conv: x = features[size_t(i)]->as<nn::Conv2dImpl>()->forward(x); break;
      case Layer::Relu: x = torch::relu(x); break;
      case Layer::MaxPool:
        x = backbone == Backbone::AlexNet ? torch::max_pool2d(x, 3, 2) : torch::max_pool2d(x, 2, 2);
        break;
      case Layer::AvgPool: x = torch::avg_pool2d(x, 2, 2); break;
    }
  }
  return x;
}

io::LoadReport load_backbone(VggFeaturesImpl& backbone, const std::string& path) {
  io::NamedTensors all = io::read_weight_file(path), features;
  int64_t ignored = 0;
  for (auto& [k, v] : all) {
    if (k.rfind("features.", 0) == 0)
      features[k] = v;
    else
      ++ignored;
  }
  if (features.empty())
    throw std::runtime_error(
        fmt::format("{}: no `features.N.weight/bias` tensors (a torchvision-format backbone "
                    "file is expected)",
                    path));
  auto report = io::load_state_dict(backbone, features, path);
  for (int64_t i = 0; i < ignored; ++i) report.skipped.push_back("(non-features key)");
  for (auto& p : backbone.parameters()) p.set_requires_grad(false);
  backbone.eval();
  return report;
}

}  // namespace uplvsm::backbones
