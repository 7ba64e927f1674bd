// LPIPS v0.1 against the official package (../shared/fixtures/lpips): seeded random torchvision backbones, the real
// lin weights read from the official legacy-format .pth files and from the safetensors copies.
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/eval/lpips.h"
#include "uplvsm/io/safetensors.h"

using namespace uplvsm;

namespace {
struct Case {
  std::string name, backbone;
  eval::LpipsNet net;
  std::vector<std::string> layers;
};
const std::vector<Case> kCases = {
    {"alex", "alexnet_features.safetensors", eval::LpipsNet::Alex, {"relu1", "relu2", "relu3", "relu4", "relu5"}},
    {"vgg",
     "vgg16_features.safetensors",
     eval::LpipsNet::Vgg,
     {"relu1_2", "relu2_2", "relu3_3", "relu4_3", "relu5_3"}}};
}  // namespace

TEST(Lpips, MatchesOfficialPackage) {
  UPLVSM_NEEDS_FIXTURES();
  auto io = io::read_safetensors(test::fixture("lpips/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  for (const auto& c : kCases) {
    for (std::string lin : {c.name + ".pth", "lin_" + c.name + ".safetensors"}) {
      auto lpips = eval::load_lpips(c.net, test::fixture("lpips/" + c.backbone), test::fixture("lpips/" + lin));
      auto scaled = lpips->scale_input(io.at("in0").narrow(0, 0, 1));
      EXPECT_LE(test::max_abs_diff(scaled, io.at(c.name + ".scaled_input0")), 1e-6) << lin;
      auto feats = lpips->features(scaled);
      for (size_t k = 0; k < 5; ++k) {
        const auto& ref = io.at(c.name + ".feat0." + c.layers[k]);
        EXPECT_LE(test::max_abs_diff(feats[k], ref), 1e-5 * std::max(1.0, ref.abs().max().item<double>()))
            << lin << " " << c.layers[k];
      }
      EXPECT_LE(test::max_abs_diff(lpips->per_layer(io.at("in0"), io.at("in1")), io.at(c.name + ".per_layer")), 1e-5)
          << lin;
      EXPECT_LE(test::max_abs_diff(lpips->per_layer(io.at("in0"), io.at("in1"), false),
                                   io.at(c.name + ".per_layer_unweighted")),
                1e-5)
          << lin;
      auto value = lpips->forward(io.at("in0"), io.at("in1"));
      EXPECT_LE(test::max_abs_diff(value, io.at(c.name + ".lpips")), 1e-5) << lin;
      // Leading dims are kept: [2, 2, 3, H, W] -> [2, 2].
      auto pairs = lpips->forward(io.at("in0").view({2, 2, 3, 64, 64}), io.at("in1").view({2, 2, 3, 64, 64}));
      EXPECT_LE(test::max_abs_diff(pairs.flatten(), io.at(c.name + ".lpips")), 1e-6) << lin;
    }
  }
}

TEST(Lpips, IdenticalImagesScoreZeroAndErrorsAreNamed) {
  UPLVSM_NEEDS_FIXTURES();
  auto lpips = eval::load_lpips(eval::LpipsNet::Alex, test::fixture("lpips/alexnet_features.safetensors"),
                                test::fixture("lpips/alex.pth"));
  torch::NoGradGuard no_grad;
  auto x = torch::rand({2, 3, 64, 64});
  EXPECT_LE(lpips->forward(x, x).abs().max().item<double>(), 1e-7);
  // vgg lin weights into the alex network: shape error naming the file and key.
  auto msg = test::error_of([] {
    eval::load_lpips(eval::LpipsNet::Alex, test::fixture("lpips/alexnet_features.safetensors"),
                     test::fixture("lpips/vgg.pth"));
  });
  EXPECT_NE(msg.find("vgg.pth"), std::string::npos) << msg;
  EXPECT_NE(msg.find("lin1.model.1.weight"), std::string::npos) << msg;
  // A backbone file of the wrong network: the strict loader lists the mis-shaped keys.
  auto wrong = test::error_of([] {
    eval::load_lpips(eval::LpipsNet::Vgg, test::fixture("lpips/alexnet_features.safetensors"),
                     test::fixture("lpips/vgg.pth"));
  });
  EXPECT_NE(wrong.find("features.0.weight"), std::string::npos) << wrong;
  EXPECT_THROW(eval::parse_lpips_net("squeeze"), std::runtime_error);
}
