// The LVSM perceptual loss: a hand-computed case (identity first conv, everything after it zero), the ImageNet
// preprocessing for MatConvNet's and torchvision's weights, a finite-difference gradient check, and loading VGG19
// weights (their input preparation from the file's marker or the caller, and refusing a VGG16 file).
#include "uplvsm/train/perceptual_loss.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"

using namespace uplvsm;

namespace {

// All conv weights and biases zero, then conv 0 copies the 3 input channels to its first 3 outputs (centre tap) and
// conv 2 copies its 64 inputs: relu1_2 = relu(preprocessed input) on 3 of 64 channels; deeper features are 0.
train::PerceptualLoss identity_first_block(train::VggInput input = train::VggInput::MatConvNet) {
  train::PerceptualLoss loss(input);
  torch::NoGradGuard no_grad;
  for (auto& p : loss->parameters()) p.zero_();
  auto conv = [&](int64_t i) { return loss->vgg->features[size_t(i)]->as<torch::nn::Conv2dImpl>(); };
  for (int64_t c = 0; c < 3; ++c) conv(0)->weight[c][c][1][1] = 1.0;
  for (int64_t c = 0; c < 64; ++c) conv(2)->weight[c][c][1][1] = 1.0;
  return loss;
}

}  // namespace

TEST(PerceptualLoss, HandComputedCase) {
  auto loss = identity_first_block();
  auto pred = torch::full({1, 3, 16, 16}, 0.5), target = torch::full({1, 3, 16, 16}, 0.25);
  // Pixel term: |255 * 0.5 - 255 * 0.25| = 63.75 everywhere (the mean cancels).
  // relu1_2: pred 127.5 - (123.68, 116.779, 103.939) = (3.82, 10.721, 23.561); target values are negative -> 0.
  const double f1 = (3.82 + 10.721 + 23.561) / 64.0;
  const double expected = (63.75 + f1 / 2.6) / 255.0;
  auto terms = loss->terms(pred, target);
  EXPECT_NEAR(terms[0].item<double>(), 63.75 / 255.0, 1e-6);
  EXPECT_NEAR(terms[1].item<double>(), f1 / 2.6 / 255.0, 1e-6);
  for (int64_t k = 2; k < 6; ++k) EXPECT_EQ(terms[k].item<double>(), 0.0) << k;
  EXPECT_NEAR(loss->forward(pred, target).item<double>(), expected, 1e-6);
  // Leading dims are flattened: [b, v, 3, H, W] gives the same mean.
  EXPECT_NEAR(loss->forward(pred.expand({2, 2, 3, 16, 16}), target.expand({2, 2, 3, 16, 16})).item<double>(), expected,
              1e-6);
  EXPECT_EQ(loss->forward(pred, pred).item<double>(), 0.0);
}

// torchvision's vgg19() weights see [0, 1] normalised by the ImageNet mean and std; the pixel term stays the official
// 0..255 one.
TEST(PerceptualLoss, TorchvisionWeightsSeeImageNetNormalisedInput) {
  auto loss = identity_first_block(train::VggInput::TorchVision);
  auto pred = torch::full({1, 3, 16, 16}, 0.5), target = torch::full({1, 3, 16, 16}, 0.25);
  const auto pre = loss->preprocess(pred);
  const double mean[3] = {0.485, 0.456, 0.406}, stdev[3] = {0.229, 0.224, 0.225};
  double f1 = 0;  // relu1_2 of pred; the target's values are all negative -> 0
  for (int c = 0; c < 3; ++c) {
    const double expected = (0.5 - mean[c]) / stdev[c];
    EXPECT_NEAR(pre[0][c][3][5].item<double>(), expected, 1e-6) << c;
    f1 += std::max(expected, 0.0) - std::max((0.25 - mean[c]) / stdev[c], 0.0);
  }
  auto terms = loss->terms(pred, target);
  EXPECT_NEAR(terms[0].item<double>(), 63.75 / 255.0, 1e-6);
  EXPECT_NEAR(terms[1].item<double>(), f1 / 64.0 / 2.6 / 255.0, 1e-7);
  // The official preparation of the same weights gives another relu1_2 term: the two are told apart.
  EXPECT_GT(std::abs(identity_first_block()->terms(pred, target)[1].item<double>() - terms[1].item<double>()), 5e-4);
}

TEST(PerceptualLoss, SlicesAndWeightsAreLvsms) {
  EXPECT_EQ(train::perceptual_slice_ends(), (std::vector<int64_t>{4, 9, 14, 23, 32}));
  const auto& d = train::perceptual_term_divisors();
  ASSERT_EQ(d.size(), 6u);
  EXPECT_DOUBLE_EQ(d[5], 0.15);  // 10 * L1 / 1.5
  train::PerceptualLoss loss;
  // relu5_2 of a 32x32 input: four 2x2 average pools before it -> 2x2, 512 channels.
  auto f = loss->features(torch::zeros({1, 3, 32, 32}));
  ASSERT_EQ(f.size(), 5u);
  EXPECT_EQ(f[4].sizes(), (std::vector<int64_t>{1, 512, 2, 2}));
  EXPECT_EQ(f[2].sizes(), (std::vector<int64_t>{1, 256, 8, 8}));
  for (const auto& p : loss->parameters()) EXPECT_FALSE(p.requires_grad());
}

// Every term is divided by the official loss.py constant (2.6, 4.8, 3.7, 5.6, 1.5 / 10, then 255): random weights so
// every layer's features differ, each term recomputed here from the features with the literal divisors.
TEST(PerceptualLoss, EachLayerTermUsesTheOfficialDivisor) {
  torch::manual_seed(3);
  train::PerceptualLoss loss;
  auto pred = torch::rand({2, 3, 32, 32}), target = torch::rand({2, 3, 32, 32});
  const auto terms = loss->terms(pred, target);
  const auto fp = loss->features(loss->preprocess(pred)), ft = loss->features(loss->preprocess(target));
  const double official[5] = {2.6, 4.8, 3.7, 5.6, 1.5 / 10};
  for (int k = 0; k < 5; ++k) {
    const double l1 = (fp[size_t(k)] - ft[size_t(k)]).abs().mean().item<double>();
    ASSERT_GT(l1, 0) << k;
    EXPECT_NEAR(terms[k + 1].item<double>(), l1 / official[k] / 255.0, 1e-6 * l1) << "layer " << k + 1;
  }
  EXPECT_NEAR(terms[0].item<double>(), (pred - target).abs().mean().item<double>(), 1e-6);  // 255 |a - b| / 255
}

TEST(PerceptualLoss, GradientMatchesFiniteDifferences) {
  torch::manual_seed(3);
  train::PerceptualLoss loss;
  {
    torch::NoGradGuard no_grad;
    for (auto& p : loss->parameters()) p.mul_(0.5);  // keep activations moderate
  }
  loss->to(torch::kFloat64);
  auto pred = torch::rand({2, 3, 16, 16}, torch::kFloat64).requires_grad_(true);
  auto target = torch::rand({2, 3, 16, 16}, torch::kFloat64);
  auto value = loss->forward(pred, target);
  value.backward();
  auto grad = pred.grad().flatten();
  ASSERT_GT(grad.abs().max().item<double>(), 0.0);
  const double eps = 1e-6;
  auto flat = pred.detach().flatten();
  for (int64_t i : {0L, 77L, 300L, 511L, 1000L, 1535L}) {
    auto plus = flat.clone(), minus = flat.clone();
    plus[i] += eps;
    minus[i] -= eps;
    torch::NoGradGuard no_grad;
    const double numeric =
        (loss->forward(plus.view_as(pred), target) - loss->forward(minus.view_as(pred), target)).item<double>() /
        (2 * eps);
    EXPECT_NEAR(grad[i].item<double>(), numeric, 1e-6 + 1e-4 * std::abs(numeric)) << "element " << i;
  }
}

TEST(PerceptualLoss, LoadsVgg19Weights) {
  torch::manual_seed(5);
  train::PerceptualLoss source;
  const auto dir = test::temp_dir("perceptual_weights");
  const auto path = (dir / "vgg19.safetensors").string();
  io::TensorMap tensors;
  for (const auto& [k, v] : io::state_dict(*source->vgg)) tensors[k] = v;
  tensors["classifier.0.weight"] = torch::zeros({4, 4});  // torchvision files carry the classifier too
  io::write_safetensors(path, tensors);
  auto loaded = train::load_perceptual_loss(path, train::VggInput::TorchVision);
  for (const auto& [k, v] : io::state_dict(*loaded->vgg)) EXPECT_TRUE(torch::equal(v, tensors.at(k))) << k;
  EXPECT_FALSE(loaded->is_training());
  EXPECT_EQ(loaded->input, train::VggInput::TorchVision);
  test::remove_tree(dir);
}

// Which input the weights expect: the marker `uplvsm convert` writes decides, a caller's choice serves unmarked
// files, and an unmarked file without one is refused naming the fix (the two kinds have the same names and shapes).
TEST(PerceptualLoss, InputPreparationComesFromTheFileOrTheCaller) {
  const auto dir = test::temp_dir("perceptual_input");
  io::TensorMap tensors;
  for (const auto& [k, v] : io::state_dict(*train::PerceptualLoss()->vgg)) tensors[k] = v;
  const auto marked = (dir / "marked.safetensors").string(), unmarked = (dir / "plain.safetensors").string();
  io::write_safetensors(marked, tensors, {{train::kVggInputMetadataKey, "matconvnet"}});
  io::write_safetensors(unmarked, tensors);
  using train::VggInput;
  EXPECT_EQ(train::load_perceptual_loss(marked)->input, VggInput::MatConvNet);
  EXPECT_EQ(train::resolve_vgg_input(marked, VggInput::MatConvNet), VggInput::MatConvNet);
  auto contradiction = test::error_of([&] { train::resolve_vgg_input(marked, VggInput::TorchVision); });
  EXPECT_NE(contradiction.find("marked as taking matconvnet input, not torchvision"), std::string::npos)
      << contradiction;
  EXPECT_EQ(train::resolve_vgg_input(unmarked, VggInput::TorchVision), VggInput::TorchVision);
  EXPECT_EQ(train::resolve_vgg_input(unmarked, VggInput::MatConvNet), VggInput::MatConvNet);
  auto refused = test::error_of([&] { train::load_perceptual_loss(unmarked); });
  EXPECT_NE(refused.find("plain.safetensors: cannot tell which input"), std::string::npos) << refused;
  EXPECT_NE(refused.find("--vgg19-input torchvision"), std::string::npos) << refused;
  EXPECT_EQ(train::parse_vgg_input("torchvision"), VggInput::TorchVision);
  EXPECT_THROW(train::parse_vgg_input("caffe"), std::runtime_error);
  test::remove_tree(dir);
}

TEST(PerceptualLoss, RefusesOtherVggWeights) {
  UPLVSM_NEEDS_FIXTURES();
  auto err = test::error_of([] {
    train::load_perceptual_loss(test::fixture("lpips/vgg16_features.safetensors"), train::VggInput::TorchVision);
  });
  EXPECT_NE(err.find("vgg16_features.safetensors"), std::string::npos) << err;
}
