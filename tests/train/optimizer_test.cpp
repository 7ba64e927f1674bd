#include <gtest/gtest.h>

#include "train_test_util.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/optimizer.h"

using namespace uplvsm;

TEST(Optimizer, OfficialParamGroups) {
  model::UPLVSM net(test::micro_config().model);
  auto g = train::split_param_groups(*net);
  auto has = [](const std::vector<std::string>& v, const std::string& k) {
    return std::find(v.begin(), v.end(), k) != v.end();
  };
  // dim > 1 (decayed): matrices, and also the latents, tokens, pos_embed and conv patch embed.
  EXPECT_TRUE(has(g.decay_names, "n_light_field_latent"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.pos_embed"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.cls_token"));
  EXPECT_TRUE(has(g.decay_names, "image_tokenizer.1.dino_vit.patch_embed.proj.weight"));
  EXPECT_TRUE(has(g.decay_names, "transformer_decoder.0.attn.to_qkv.weight"));
  // dim <= 1: norms, biases, LayerScale.
  EXPECT_TRUE(has(g.no_decay_names, "transformer_decoder.0.norm1.weight"));
  EXPECT_TRUE(has(g.no_decay_names, "image_tokenizer.1.dino_vit.blocks.0.ls1.gamma"));
  EXPECT_TRUE(has(g.no_decay_names, "estimator.absT_head.fc1.bias"));
  EXPECT_EQ(g.decay.size() + g.no_decay.size(), net->parameters().size());
}

TEST(Optimizer, WarmupThenCosine) {
  EXPECT_DOUBLE_EQ(train::lr_lambda(0, 100, 1000), 0.0);
  EXPECT_DOUBLE_EQ(train::lr_lambda(50, 100, 1000), 0.5);
  EXPECT_DOUBLE_EQ(train::lr_lambda(100, 100, 1000), 1.0);
  EXPECT_NEAR(train::lr_lambda(550, 100, 1000), 0.5, 1e-12);
  EXPECT_NEAR(train::lr_lambda(1000, 100, 1000), 0.0, 1e-12);
}

// The moments exist before the first step (allocated next to the weights), as the zeros AdamW's first step would
// create: two steps move the weights and moments exactly as an AdamW left to create its state lazily.
TEST(Optimizer, MomentsAllocatedUpFrontStepLikeLazyOnes) {
  torch::manual_seed(5);
  auto eager_net = torch::nn::Linear(6, 4), lazy_net = torch::nn::Linear(6, 4);
  {
    torch::NoGradGuard no_grad;
    lazy_net->weight.copy_(eager_net->weight);
    lazy_net->bias.copy_(eager_net->bias);
  }
  TrainingConfig tc;
  tc.lr = 1e-2;
  tc.weight_decay = 0.05;
  auto eager = train::make_optimizer(*eager_net, tc);
  ASSERT_EQ(eager->state().size(), 2u);
  for (const auto& [key, state] : eager->state()) {
    const auto& s = static_cast<torch::optim::AdamWParamState&>(*state);
    EXPECT_EQ(s.step(), 0);
    EXPECT_EQ(s.exp_avg().abs().max().item<float>(), 0.f);
    EXPECT_EQ(s.exp_avg_sq().abs().max().item<float>(), 0.f);
  }
  torch::optim::AdamW lazy(train::official_param_groups(*lazy_net, tc), torch::optim::AdamWOptions(tc.lr));
  ASSERT_TRUE(lazy.state().empty());
  for (int step = 0; step < 2; ++step) {
    const auto x = torch::randn({3, 6});
    for (auto net : {eager_net, lazy_net}) {  // a holder copy shares its module
      net->zero_grad();
      net->forward(x).pow(2).sum().backward();
    }
    eager->step();
    lazy.step();
  }
  EXPECT_TRUE(eager_net->weight.equal(lazy_net->weight));
  EXPECT_TRUE(eager_net->bias.equal(lazy_net->bias));
  const auto& eager_state = static_cast<torch::optim::AdamWParamState&>(
      *eager->state().at(train::state_key(eager->state(), eager_net->weight)));
  const auto& lazy_state =
      static_cast<torch::optim::AdamWParamState&>(*lazy.state().at(train::state_key(lazy.state(), lazy_net->weight)));
  EXPECT_EQ(eager_state.step(), 2);
  EXPECT_TRUE(eager_state.exp_avg_sq().equal(lazy_state.exp_avg_sq()));
}

namespace {
// Two AdamW optimisers over identical copies of the same parameters (a decayed and an undecayed group).
struct AdamWPair {
  std::vector<torch::Tensor> a, b;
  std::unique_ptr<torch::optim::AdamW> torch_adamw, fused_adamw;
};

AdamWPair adamw_pair(const std::vector<std::vector<int64_t>>& shapes, double weight_decay) {
  AdamWPair pair;
  for (const auto& shape : shapes) {
    auto t = torch::randn(shape);
    pair.a.push_back(t.clone().requires_grad_());
    pair.b.push_back(t.clone().requires_grad_());
  }
  auto make = [&](const std::vector<torch::Tensor>& params) {
    const auto half = params.begin() + static_cast<std::ptrdiff_t>(params.size() / 2);
    auto options = [&](double wd) {
      return std::make_unique<torch::optim::AdamWOptions>(
          torch::optim::AdamWOptions(1e-3).betas({0.9, 0.95}).eps(1e-8).weight_decay(wd));
    };
    std::vector<torch::optim::OptimizerParamGroup> groups;
    groups.emplace_back(std::vector<torch::Tensor>(params.begin(), half), options(weight_decay));
    groups.emplace_back(std::vector<torch::Tensor>(half, params.end()), options(0.0));
    return std::make_unique<torch::optim::AdamW>(groups, torch::optim::AdamWOptions(1e-3));
  };
  pair.torch_adamw = make(pair.a);
  pair.fused_adamw = make(pair.b);
  return pair;
}

void set_same_gradients(AdamWPair& pair, int step) {
  for (size_t i = 0; i < pair.a.size(); ++i) {
    // Gradients over many magnitudes (and exact zeros), so every rounding step of the update matters.
    auto g = torch::randn(pair.a[i].sizes()) * std::pow(10.0, static_cast<double>((step + i) % 7) - 4.0);
    g.index_put_({g.abs() < 1e-5}, 0.0);
    pair.a[i].mutable_grad() = g.clone();
    pair.b[i].mutable_grad() = g.clone();
  }
}

// Bit for bit against the LibTorch the project ships with (Debian's 1.13). PyPI's LibTorch 2.11 (lent H200 machines,
// 2026-11-27/28) rounds a few elements of a threaded parameter apart (1.9e-9, then 4.7e-10 on an element the step
// nearly cancelled): its vector kernels, not the update's formula. There the two must agree within two fp32 roundings
// of the operands: `scale` is their size (the value before the step plus the one after; for a moment, its value).
bool same_update(const torch::Tensor& ours, const torch::Tensor& libtorch, const torch::Tensor& scale) {
#if TORCH_VERSION_MAJOR >= 2
  return ((ours - libtorch).abs() <= std::ldexp(1.0, -22) * scale).all().item<bool>();
#else
  (void)scale;
  return torch::equal(ours, libtorch);
#endif
}
}  // namespace

// The one-pass step gives LibTorch's AdamW::step bit for bit — weights and both moments, both groups, a learning
// rate that changes between steps, tensors on one thread and split across threads (> 16384 elements, odd tails), a
// parameter without a gradient left alone — and bumps the version counters the in-place ops would.
TEST(Optimizer, OnePassAdamWStepIsLibTorchsStepBitForBit) {
  torch::manual_seed(11);
  auto pair = adamw_pair({{37, 129}, {3, 5}, {40001}, {128}, {7}, {20000, 3}}, 0.05);
  for (int step = 0; step < 6; ++step) {
    set_same_gradients(pair, step);
    if (step == 4) {  // no gradient this step: neither optimiser touches it, nor advances its step count
      pair.a[1].mutable_grad().reset();
      pair.b[1].mutable_grad().reset();
    }
    const double lr = 1e-3 * (1.0 + 0.37 * step);
    train::set_learning_rate(*pair.torch_adamw, lr);
    train::set_learning_rate(*pair.fused_adamw, lr);
    std::vector<int64_t> versions;
    std::vector<torch::Tensor> before;
    for (const auto& p : pair.b) {
      versions.push_back(static_cast<int64_t>(p._version()));
      before.push_back(p.detach().clone());
    }
    pair.torch_adamw->step();
    train::adamw_step(*pair.fused_adamw);
    for (size_t i = 0; i < pair.a.size(); ++i) {
      ASSERT_TRUE(same_update(pair.b[i], pair.a[i], before[i].abs() + pair.a[i].abs()))
          << "step " << step << ", parameter " << i << ": max |diff| "
          << (pair.a[i] - pair.b[i]).abs().max().item<double>();
      const bool updated = pair.b[i].grad().defined();
      EXPECT_EQ(static_cast<int64_t>(pair.b[i]._version()) > versions[i], updated) << "parameter " << i;
    }
  }
  auto& ta = pair.torch_adamw->state();
  auto& fa = pair.fused_adamw->state();
  for (size_t i = 0; i < pair.a.size(); ++i) {
    const auto& s = static_cast<torch::optim::AdamWParamState&>(*ta.at(train::state_key(ta, pair.a[i])));
    const auto& f = static_cast<torch::optim::AdamWParamState&>(*fa.at(train::state_key(fa, pair.b[i])));
    EXPECT_EQ(s.step(), f.step());
    EXPECT_TRUE(same_update(f.exp_avg(), s.exp_avg(), s.exp_avg().abs())) << "parameter " << i;
    EXPECT_TRUE(same_update(f.exp_avg_sq(), s.exp_avg_sq(), s.exp_avg_sq())) << "parameter " << i;
  }
}

// What the one pass does not cover takes LibTorch's own step: a bf16 parameter, or AMSGrad.
TEST(Optimizer, OnePassAdamWStepFallsBackToLibTorchsStep) {
  torch::manual_seed(12);
  auto pair = adamw_pair({{9, 4}, {6}}, 0.1);
  for (auto* params : {&pair.a, &pair.b}) {
    torch::NoGradGuard no_grad;
    (*params)[1].set_data((*params)[1].to(torch::kBFloat16));
  }
  for (int step = 0; step < 3; ++step) {
    set_same_gradients(pair, step);
    pair.a[1].mutable_grad() = pair.a[1].grad().to(torch::kBFloat16);
    pair.b[1].mutable_grad() = pair.b[1].grad().to(torch::kBFloat16);
    pair.torch_adamw->step();
    train::adamw_step(*pair.fused_adamw);
    for (size_t i = 0; i < pair.a.size(); ++i) EXPECT_TRUE(torch::equal(pair.a[i], pair.b[i])) << "parameter " << i;
  }
}
