// Tests of model/cast_once_linear: bit-equal to torch::nn::Linear under bf16 autocast, fp32 and with gradients;
// the bf16 copy follows every change of the weights.
#include "uplvsm/model/linear.h"

#include <c10/core/impl/LocalDispatchKeySet.h>
#include <gtest/gtest.h>

#include "uplvsm/core/autocast.h"

using namespace uplvsm;
using namespace uplvsm::model;
using namespace uplvsm::kernels;

namespace {

// What autocast computes for a linear layer: operands rounded to bf16 (cast here explicitly, since autocast's own
// cache would keep a stale copy of a weight changed in place within one region), or fp32 as it is.
torch::Tensor reference(const Linear& layer, const torch::Tensor& x) {
  if (!autocast_active(x.device())) return torch::linear(x, layer->weight, layer->bias);
  c10::impl::ExcludeDispatchKeyGuard no_autocast(c10::autocast_dispatch_keyset);
  auto b = layer->bias.defined() ? layer->bias.to(torch::kBFloat16) : torch::Tensor();
  return torch::linear(x.to(torch::kBFloat16), layer->weight.to(torch::kBFloat16), b);
}

TEST(Linear, InferenceUnderAutocastEqualsLinearBitForBit) {
  torch::manual_seed(1);
  Linear layer(torch::nn::LinearOptions(48, 80).bias(true));
  auto x = torch::randn({3, 7, 48});
  torch::NoGradGuard no_grad;
  AutocastGuard autocast(torch::kCPU, true);
  for (int call = 0; call < 3; ++call) {
    auto y = layer(x);
    EXPECT_EQ(y.scalar_type(), torch::kBFloat16);
    EXPECT_TRUE(torch::equal(y, reference(layer, x)));
  }
}

TEST(Linear, FollowsEveryChangeOfTheWeights) {
  torch::manual_seed(2);
  Linear layer(torch::nn::LinearOptions(32, 16).bias(true));
  auto x = torch::randn({5, 32});
  torch::NoGradGuard no_grad;
  AutocastGuard autocast(torch::kCPU, true);
  auto before = layer(x);
  layer->weight.add_(0.5);  // an optimizer step
  auto after_weight = layer(x);
  EXPECT_FALSE(torch::equal(before, after_weight));
  EXPECT_TRUE(torch::equal(after_weight, reference(layer, x)));
  layer->bias.copy_(torch::randn({16}));  // a state-dict load copies into the parameters
  EXPECT_TRUE(torch::equal(layer(x), reference(layer, x)));
  layer->weight.set_data(torch::randn({16, 32}));  // new storage
  EXPECT_TRUE(torch::equal(layer(x), reference(layer, x)));
}

TEST(Linear, TrainingAndFp32TakeLinearsOwnPath) {
  torch::manual_seed(3);
  Linear layer(torch::nn::LinearOptions(24, 8).bias(false));
  auto x = torch::randn({4, 24});
  EXPECT_TRUE(torch::equal(layer(x), reference(layer, x)));  // fp32
  {
    AutocastGuard autocast(torch::kCPU, true);
    auto y = layer(x);
    y.sum().backward();
  }
  ASSERT_TRUE(layer->weight.grad().defined());
  EXPECT_EQ(layer->weight.grad().scalar_type(), torch::kFloat32);
  EXPECT_GT(layer->weight.grad().abs().sum().item<double>(), 0.0);
}

// With a bias and tokens ([batch, tokens, features], as DINOv2's blocks call it), training computes ATen's linear too:
// the bias inside the bf16 matmul, one rounding — not LibTorch 1.13's nn::Linear, which rounds the product to bf16
// and then adds the fp32 bias in a second pass.
TEST(Linear, TrainingWithABiasOnTokensIsATensLinear) {
  torch::manual_seed(4);
  Linear layer(torch::nn::LinearOptions(40, 24).bias(true));
  {
    torch::NoGradGuard no_grad;
    layer->bias.copy_(torch::randn({24}) * 3.0);  // large enough that a second rounding shows
  }
  auto x = torch::randn({2, 9, 40});
  AutocastGuard autocast(torch::kCPU, true);
  auto y = layer(x);
  EXPECT_TRUE(torch::equal(y, reference(layer, x)));
  y.sum().backward();
  ASSERT_TRUE(layer->bias.grad().defined());
  EXPECT_EQ(layer->bias.grad().scalar_type(), torch::kFloat32);
}

}  // namespace
