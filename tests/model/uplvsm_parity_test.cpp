// The whole UP-LVSM forward against the official code's outputs (../shared/fixtures/official_uplvsm, random
// weights, fp32): DINOv2 reg4 + QK-norm tokenizer, canonical marker, latents, encoder, estimator, decoder.
#include <gtest/gtest.h>

#include "official_fixture.h"
#include "test_util.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/model/uplvsm.h"

using namespace uplvsm;
using torch::indexing::Slice;

TEST(OfficialParity, ForwardMatchesOfficialUplvsm) {
  UPLVSM_NEEDS_FIXTURES();
  model::UPLVSM net(test::official_fixture_model_config());
  auto weights = io::read_safetensors(test::fixture("official_uplvsm/model.safetensors")).tensors;
  auto report = io::load_state_dict(*net, weights, "official_uplvsm/model.safetensors");
  EXPECT_EQ(report.loaded, 93);
  net->eval();
  auto f = io::read_safetensors(test::fixture("official_uplvsm/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  model::ForwardTrace trace;
  auto out = net->forward(f.at("input.images"), f.at("input.fxfycxcy"), f.at("target.images"), f.at("target.fxfycxcy"),
                          &trace);
  EXPECT_LE(
      test::max_abs_diff(net->tokenizer->dino_vit->interpolate_pos_encoding(126, 126), f.at("inter.dino_pos_embed")),
      1e-5);
  EXPECT_LE(test::max_abs_diff(trace.input_dino_tokens, f.at("inter.input_dino_tokens")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.canonical_plucker, f.at("inter.canonical_plucker")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.encoder_output, f.at("inter.encoder_output")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.encoder_output.index({Slice(), Slice(0, 24)}), f.at("inter.latent_tokens")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.target_dino_tokens, f.at("inter.target_dino_tokens")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.estimator_pooled, f.at("inter.estimator_pooled")), 1e-4);
  EXPECT_LE(test::max_abs_diff(out.pose_enc, f.at("out.pose_enc")), 1e-4);
  EXPECT_LE(test::max_abs_diff(trace.target_plucker, f.at("out.target_plucker")), 1e-4);
  EXPECT_LE(test::max_abs_diff(out.render, f.at("out.render")), 1e-4);
  auto mse = (out.render - f.at("target.images")).pow(2).mean();
  EXPECT_NEAR(mse.item<double>(), f.at("out.l2_loss").item<double>(), 1e-6);
}
