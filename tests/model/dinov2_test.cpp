// Meta's DINOv2 forward (no registers, 0.1-offset bicubic pos-embed interpolation) against
// ../shared/fixtures/dinov2, with the official-names safetensors weights.
#include <gtest/gtest.h>

#include "official_fixture.h"
#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/dinov2.h"

using namespace uplvsm;

namespace {
model::Dinov2 fixture_dinov2() {
  model::Dinov2 vit(test::meta_fixture_dinov2(), 14);
  auto weights = io::read_safetensors(test::fixture("dinov2/weights.safetensors")).tensors;
  io::LoadOptions opt;
  opt.skip_prefixes = {"mask_token"};  // only used for masked-image pretraining
  auto report = io::load_state_dict(*vit, weights, "dinov2/weights.safetensors", opt);
  EXPECT_EQ(report.loaded, 2 + 2 + 2 * 14 + 2);  // cls+pos, patch embed, 14 per block, final norm
  vit->eval();
  return vit;
}
}  // namespace

TEST(Dinov2, MatchesMetaForwardSquareAndNonSquare) {
  UPLVSM_NEEDS_FIXTURES();
  auto vit = fixture_dinov2();
  auto io = io::read_safetensors(test::fixture("dinov2/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  for (std::string name : {"square", "nonsquare"}) {
    auto x = io.at(name + ".input");
    EXPECT_LE(
        test::max_abs_diff(vit->interpolate_pos_encoding(x.size(2), x.size(3)), io.at(name + ".pos_embed_interp")),
        1e-5)
        << name;
    auto f = vit->forward_features(x);
    EXPECT_LE(test::max_abs_diff(f.prenorm, io.at(name + ".x_prenorm")), 1e-4) << name;
    EXPECT_LE(test::max_abs_diff(f.cls, io.at(name + ".x_norm_clstoken")), 1e-4) << name;
    EXPECT_LE(test::max_abs_diff(f.patch_tokens, io.at(name + ".x_norm_patchtokens")), 1e-4) << name;
  }
}

// The from-scratch position table: MAE's layout, hand-checked entries, and what a config selects.
TEST(Dinov2, SincosPosEmbedTableAndConfig) {
  const int64_t grid = 3, dim = 8;  // 2 frequencies: 1 and 10000^(-1/2) = 0.01
  auto pe = model::sincos_pos_embed(grid, dim);
  ASSERT_EQ(pe.sizes(), (std::vector<int64_t>{1, 1 + grid * grid, dim}));
  EXPECT_EQ(pe[0][0].abs().max().item<float>(), 0.0f);  // class token
  // Patch (row 1, col 2) is token 1 + 1 * 3 + 2 = 6: [sin 2, sin 0.02, cos 2, cos 0.02, sin 1, sin 0.01, cos 1, cos
  // 0.01].
  auto row = pe[0][6];
  const double expected[8] = {std::sin(2.0), std::sin(0.02), std::cos(2.0), std::cos(0.02),
                              std::sin(1.0), std::sin(0.01), std::cos(1.0), std::cos(0.01)};
  for (int k = 0; k < 8; ++k) EXPECT_NEAR(row[k].item<double>(), expected[k], 1e-6) << k;
  // Every patch has its own row.
  auto patches = pe[0].slice(0, 1);
  EXPECT_GT(torch::cdist(patches, patches).add(torch::eye(grid * grid) * 10).min().item<float>(), 1e-3);

  Dinov2Config c;
  c.embed_dim = dim, c.depth = 1, c.num_heads = 2, c.pos_grid = grid, c.num_register_tokens = 0;
  EXPECT_FALSE(torch::equal(model::Dinov2(c, 4)->pos_embed.detach(), pe));  // "normal": drawn (init_test.cpp)
  c.pos_embed_init = "sincos";
  EXPECT_TRUE(torch::equal(model::Dinov2(c, 4)->pos_embed.detach(), pe));
}
