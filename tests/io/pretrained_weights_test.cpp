// The weight files users bring: official UP-LVSM checkpoint.pt -> same outputs as the official forward; DINOv2 from
// Meta .pth and HuggingFace safetensors -> same tokens; inferred configs; wrong-shape / missing-key errors.
#include <gtest/gtest.h>

#include "official_fixture.h"
#include "test_util.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"

using namespace uplvsm;

namespace {
void expect_meta_tokens(model::Dinov2Impl& vit, const std::string& what) {
  auto io = io::read_safetensors(test::fixture("dinov2/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  vit.eval();
  for (std::string name : {"square", "nonsquare"}) {
    auto f = vit.forward_features(io.at(name + ".input"));
    EXPECT_LE(test::max_abs_diff(f.patch_tokens, io.at(name + ".x_norm_patchtokens")), 1e-4) << what << " " << name;
    EXPECT_LE(test::max_abs_diff(f.cls, io.at(name + ".x_norm_clstoken")), 1e-4) << what << " " << name;
  }
}
}  // namespace

TEST(PretrainedWeights, Dinov2FromAllThreeFiles) {
  UPLVSM_NEEDS_FIXTURES();
  for (std::string file : {"weights.pth", "weights.safetensors", "weights_hf.safetensors"}) {
    auto w = io::read_pretrained_weights(test::fixture("dinov2/" + file));
    EXPECT_EQ(w.source,
              file == "weights_hf.safetensors" ? io::WeightSource::Dinov2HuggingFace : io::WeightSource::Dinov2Meta)
        << file;
    model::Dinov2 vit(test::meta_fixture_dinov2(), 14);
    io::LoadOptions opt;
    opt.skip_prefixes = {"mask_token"};
    auto report = io::load_state_dict(*vit, w.tensors, file, opt);
    EXPECT_EQ(report.loaded, 2 + 2 + 2 * 14 + 2) << file;
    expect_meta_tokens(*vit, file);
  }
}

TEST(PretrainedWeights, HuggingFaceUnknownKeyIsAnError) {
  io::NamedTensors hf = {{"embeddings.cls_token", torch::zeros({1, 1, 4})},
                         {"encoder.layer.0.mlp.weights_in.weight", torch::zeros({4, 4})}};
  auto msg = test::error_of([&] { io::dinov2_from_huggingface(hf, "x.safetensors"); });
  EXPECT_NE(msg.find("encoder.layer.0.mlp.weights_in.weight"), std::string::npos) << msg;
}

TEST(PretrainedWeights, Dinov2IntoUplvsmTokenizer) {
  UPLVSM_NEEDS_FIXTURES();
  // A UP-LVSM whose tokenizer has the fixture ViT's size; Meta's file lacks the official QK-norm weights, which stay
  // at ones and are reported — and the tokenizer then reproduces Meta's tokens when QK-norm is off.
  for (bool qk_norm : {false, true}) {
    ModelConfig c;
    c.image_size = 224;
    c.transformer.d = 384;
    c.transformer.d_head = 64;
    c.transformer.encoder_n_layer = c.transformer.estimator_n_layer = c.transformer.decoder_n_layer = 1;
    c.transformer.n_latent_vectors = 4;
    c.dinov2 = test::meta_fixture_dinov2();
    c.dinov2.qk_norm = qk_norm;
    c.dinov2.imagenet_normalize = false;  // the fixture input is already normalised
    model::UPLVSM net(c);
    auto w = io::read_pretrained_weights(test::fixture("dinov2/weights.pth"));
    auto report = model::load_dinov2_into_tokenizer(*net, w.tensors, "weights.pth");
    EXPECT_TRUE(report.ok());
    EXPECT_EQ(report.defaulted.size(), qk_norm ? 4u : 0u);
    EXPECT_EQ(report.skipped, std::vector<std::string>{"mask_token"});
    if (!qk_norm)
      expect_meta_tokens(*net->tokenizer->dino_vit, "tokenizer");
    else
      EXPECT_NE(report.summary("x").find("left at their initial values"), std::string::npos);
  }
}

TEST(PretrainedWeights, InferConfigFromOfficialCheckpoint) {
  UPLVSM_NEEDS_FIXTURES();
  auto w = io::read_pretrained_weights(test::fixture("official_uplvsm/checkpoint.pt"));
  EXPECT_EQ(w.source, io::WeightSource::Uplvsm);
  EXPECT_EQ(w.container, "torch zip");
  EXPECT_EQ(w.found_at, "model");
  auto c = model::infer_model_config(w.tensors, ModelConfig{});
  EXPECT_EQ(c.transformer.d, 64);
  EXPECT_EQ(c.transformer.d_head, 32);
  EXPECT_EQ(c.transformer.encoder_n_layer, 2);
  EXPECT_EQ(c.transformer.estimator_n_layer, 1);
  EXPECT_EQ(c.transformer.decoder_n_layer, 2);
  EXPECT_EQ(c.transformer.n_latent_vectors, 24);
  EXPECT_EQ(c.patch_size, 14);
  EXPECT_EQ(c.dinov2.embed_dim, 64);
  EXPECT_EQ(c.dinov2.depth, 2);
  EXPECT_EQ(c.dinov2.num_heads, 4);
  EXPECT_EQ(c.dinov2.num_register_tokens, 4);
  EXPECT_TRUE(c.dinov2.qk_norm);
  EXPECT_EQ(c.dinov2.pos_grid, 37);
}

// The official training checkpoint, loaded with its config inferred, gives the official forward's poses and renders.
TEST(PretrainedWeights, OfficialCheckpointPtMatchesOfficialForward) {
  UPLVSM_NEEDS_FIXTURES();
  Config config;
  auto loaded = model::load_model(test::fixture("official_uplvsm/checkpoint.pt"), torch::kCPU, &config);
  auto net = model::require_uplvsm(loaded, "official checkpoint");
  EXPECT_EQ(net->parameter_count(), 667047);
  auto f = io::read_safetensors(test::fixture("official_uplvsm/io.safetensors")).tensors;
  torch::NoGradGuard no_grad;
  auto out = net->forward(f.at("input.images"), f.at("input.fxfycxcy"), f.at("target.images"), f.at("target.fxfycxcy"));
  EXPECT_LE(test::max_abs_diff(out.pose_enc, f.at("out.pose_enc")), 1e-4);
  EXPECT_LE(test::max_abs_diff(out.render, f.at("out.render")), 1e-4);

  // Same weights at another resolution (12x12 patches instead of 9x9): the pos-embed interpolation path.
  auto images = torch::nn::functional::interpolate(f.at("batch.image").flatten(0, 1),
                                                   torch::nn::functional::InterpolateFuncOptions()
                                                       .size(std::vector<int64_t>{168, 168})
                                                       .mode(torch::kBilinear)
                                                       .align_corners(false));
  images = images.view({2, 5, 3, 168, 168});
  auto K = f.at("batch.fxfycxcy") * (168.0 / 126.0);
  auto big = net->forward(images.narrow(1, 0, 2), K.narrow(1, 0, 2), images.narrow(1, 2, 3), K.narrow(1, 2, 3));
  EXPECT_EQ(big.render.sizes(), (std::vector<int64_t>{2, 3, 3, 168, 168}));
  EXPECT_TRUE(torch::isfinite(big.render).all().item<bool>());
  // At the pos-embed's own grid (37 x 14 = 518 px) the interpolation is the identity.
  auto vit = net->tokenizer->dino_vit;
  EXPECT_LE(test::max_abs_diff(vit->interpolate_pos_encoding(518, 518), vit->pos_embed), 1e-6);
}

TEST(PretrainedWeights, WrongShapeMissingAndExtraKeysAreListed) {
  UPLVSM_NEEDS_FIXTURES();
  auto weights = io::read_safetensors(test::fixture("official_uplvsm/model.safetensors")).tensors;
  weights["transformer_decoder.1.attn.fc.weight"] = torch::zeros({64, 32});
  weights.erase("estimator.quaR_head.fc2.bias");
  weights["transformer_decoder.7.attn.fc.weight"] = torch::zeros({64, 64});
  auto dir = test::temp_dir("pretrained_bad");
  auto path = (dir / "bad.safetensors").string();
  io::write_safetensors(path, weights);
  auto msg = test::error_of([&] { model::load_model(path, torch::kCPU); });
  EXPECT_NE(msg.find("transformer_decoder.1.attn.fc.weight: file [64, 32] vs model [64, 64]"), std::string::npos)
      << msg;
  EXPECT_NE(msg.find("1 missing keys (in the model, not in the file):\n    estimator.quaR_head.fc2.bias"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("transformer_decoder.7.attn.fc.weight"), std::string::npos)
      << msg;  // layers are counted 0, 1, ...

  // The same with an explicit config.
  Config hint;
  hint.model = model::infer_model_config(
      io::read_safetensors(test::fixture("official_uplvsm/model.safetensors")).tensors, hint.model);
  auto msg2 = test::error_of([&] { model::load_model(path, torch::kCPU, nullptr, &hint); });
  EXPECT_NE(msg2.find("unexpected keys"), std::string::npos) << msg2;
  EXPECT_NE(msg2.find("transformer_decoder.7.attn.fc.weight"), std::string::npos) << msg2;
}

TEST(PretrainedWeights, Dinov2FileIsNotAModel) {
  UPLVSM_NEEDS_FIXTURES();
  auto msg = test::error_of([&] { model::load_model(test::fixture("dinov2/weights.pth"), torch::kCPU); });
  EXPECT_NE(msg.find("uplvsm convert --input"), std::string::npos) << msg;
}
