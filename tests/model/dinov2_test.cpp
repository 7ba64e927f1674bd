// Meta's DINOv2 forward (no registers, 0.1-offset bicubic pos-embed interpolation) against
// ../shared/fixtures/dinov2, with the official-names safetensors weights.
#include <gtest/gtest.h>

#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/state_dict.h"

using namespace uplvsm;

namespace {
model::Dinov2 fixture_dinov2() {
  Dinov2Config c;
  c.embed_dim = 384;
  c.depth = 2;
  c.num_heads = 6;
  c.num_register_tokens = 0;
  c.qk_norm = false;
  c.interpolate_antialias = false;
  c.interpolate_offset = 0.1;
  model::Dinov2 vit(c, 14);
  auto weights = io::read_safetensors(test::fixture("dinov2/weights.safetensors")).tensors;
  model::LoadOptions opt;
  opt.skip_prefixes = {"mask_token"};  // only used for masked-image pretraining
  auto report = model::load_state_dict(*vit, weights, "dinov2/weights.safetensors", opt);
  EXPECT_EQ(report.loaded, 2 + 2 + 2 * 14 + 2);  // cls+pos, patch embed, 14 per block, final norm
  vit->eval();
  return vit;
}
}  // namespace

TEST(Dinov2, MatchesMetaForwardSquareAndNonSquare) {
  auto vit = fixture_dinov2();
  auto io = io::read_safetensors(test::fixture("dinov2/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  for (std::string name : {"square", "nonsquare"}) {
    auto x = io.at(name + ".input");
    EXPECT_LE(test::max_abs_diff(vit->interpolate_pos_encoding(x.size(2), x.size(3)), io.at(name + ".pos_embed_interp")),
              1e-5)
        << name;
    auto f = vit->forward_features(x);
    EXPECT_LE(test::max_abs_diff(f.prenorm, io.at(name + ".x_prenorm")), 1e-4) << name;
    EXPECT_LE(test::max_abs_diff(f.cls, io.at(name + ".x_norm_clstoken")), 1e-4) << name;
    EXPECT_LE(test::max_abs_diff(f.patch_tokens, io.at(name + ".x_norm_patchtokens")), 1e-4) << name;
  }
}
