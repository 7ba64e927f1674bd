// The paper's x224 configuration builds and runs one forward + backward step on the CPU (batch 1, 2 inputs,
// 1 target; the paper trains with 6 targets per scene).
#include <gtest/gtest.h>

#include <chrono>

#include "test_util.h"
#include "uplvsm/core/config.h"
#include "uplvsm/model/uplvsm.h"

using namespace uplvsm;

TEST(PaperConfig, X224ForwardBackwardOnCpu) {
  auto config = load_config(std::string(UPLVSM_SOURCE_DIR) + "/configs/paper_x224.json");
  torch::manual_seed(0);
  model::UPLVSM net(config.model);
  const int64_t params = net->parameter_count();
  // Official x224 without the VGG loss module: 260.13 M (official-uplvsm.md §10).
  EXPECT_NEAR(params / 1e6, 260.13, 0.01) << params;
  const int64_t S = config.model.image_size;
  auto inputs = torch::rand({1, 2, 3, S, S});
  auto target = torch::rand({1, 1, 3, S, S});
  auto k = torch::tensor({{{200.0f, 200.0f, 112.0f, 112.0f}, {200.0f, 200.0f, 112.0f, 112.0f}}});
  auto t0 = std::chrono::steady_clock::now();
  auto out = net->forward(inputs, k, target, k.narrow(1, 0, 1));
  auto loss = torch::mse_loss(out.render, target);
  loss.backward();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::cout << "paper_x224: " << params << " parameters, forward+backward (2 inputs, 1 target) " << seconds << " s\n";
  EXPECT_EQ(out.render.sizes(), (std::vector<int64_t>{1, 1, 3, S, S}));
  EXPECT_TRUE(std::isfinite(loss.item<double>()));
  EXPECT_TRUE(net->estimator->absT_head->fc2->weight.grad().defined());
  EXPECT_TRUE(net->tokenizer->dino_vit->pos_embed.grad().defined());
  EXPECT_GT(net->n_light_field_latent.grad().abs().sum().item<double>(), 0.0);
}
