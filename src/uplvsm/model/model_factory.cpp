#include "uplvsm/model/model_factory.h"

#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"
#include "uplvsm/model/posed_lvsm.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::model {

namespace {

const torch::Tensor& require(const io::NamedTensors& w, const std::string& key) {
  auto it = w.find(key);
  if (it == w.end()) throw std::runtime_error(fmt::format("weights lack '{}', needed to infer the model size", key));
  return it->second;
}

}  // namespace

NovelViewModel make_model(const ModelConfig& config) {
  std::shared_ptr<NovelViewModelImpl> model;
  if (config.variant == Variant::UPLVSM) {
    model = std::make_shared<UPLVSMImpl>(config);
  } else {
    const auto posed = posed_inputs(config.variant);
    TORCH_CHECK(!config.pose_mapper, "model.pose_mapper: only the uplvsm variant has latent poses to map to");
    model = std::make_shared<PosedLVSMImpl>(config, posed);
  }
  return model;
}

ModelConfig infer_model_config(const io::NamedTensors& w, ModelConfig c) {
  auto& t = c.transformer;
  if (!io::has_key(w, "n_light_field_latent") && io::has_key(w, "transformer_input_layernorm.weight")) {
    // The official posedTargetLVSM layout (decoder-only). Its keys do not tell PT-LVSM from our LVSM variant (which
    // poses every input view); the official release is PT-LVSM, so that is the default.
    if (c.variant == Variant::UPLVSM) c.variant = Variant::PTLVSM;
    c.pose_mapper = false;
    t.d = require(w, "transformer_input_layernorm.weight").size(0);
    t.d_head = require(w, "transformer_blocks.0.attn.q_norm.weight").size(0);
    t.n_layer = io::count_indexed(w, "transformer_blocks.");
  } else {
    const torch::Tensor latents = require(w, "n_light_field_latent");
    c.variant = Variant::UPLVSM;
    c.pose_mapper = io::has_key(w, "pose_mapper.A");
    t.n_latent_vectors = latents.size(0);
    t.d = latents.size(1);
    t.d_head = require(w, "transformer_encoder.0.attn.q_norm.weight").size(0);
    t.encoder_n_layer = io::count_indexed(w, "transformer_encoder.");
    t.decoder_n_layer = io::count_indexed(w, "transformer_decoder.");
    t.estimator_n_layer = io::count_indexed(w, "estimator.transformer_estimator.");
  }
  const torch::Tensor pose = require(w, "target_pose_tokenizer.1.weight");  // [d, 6 p^2]
  c.patch_size = int64_t(std::lround(std::sqrt(double(pose.size(1)) / 6.0)));
  if (6 * c.patch_size * c.patch_size != pose.size(1))
    throw std::runtime_error(fmt::format("target_pose_tokenizer.1.weight has {} inputs, not 6 p^2", pose.size(1)));

  const std::string vit = "image_tokenizer.1.dino_vit.";
  auto& dino = c.dinov2;
  dino.embed_dim = require(w, vit + "cls_token").size(2);
  dino.depth = io::count_indexed(w, vit + "blocks.");
  dino.mlp_ratio = require(w, vit + "blocks.0.mlp.fc1.weight").size(0) / dino.embed_dim;
  dino.qk_norm = io::has_key(w, vit + "blocks.0.attn.q_norm.weight");
  if (dino.qk_norm)
    dino.num_heads = dino.embed_dim / w.at(vit + "blocks.0.attn.q_norm.weight").size(0);
  else if (dino.embed_dim % 64 == 0)
    dino.num_heads = dino.embed_dim / 64;  // Meta's ViTs all use 64-wide heads
  dino.num_register_tokens = io::has_key(w, vit + "register_tokens") ? w.at(vit + "register_tokens").size(1) : 0;
  const int64_t positions = require(w, vit + "pos_embed").size(1) - 1;
  dino.pos_grid = int64_t(std::lround(std::sqrt(double(positions))));
  if (dino.pos_grid * dino.pos_grid != positions)
    throw std::runtime_error(fmt::format("{}pos_embed covers {} patches, not a square grid", vit, positions));
  return c;
}

NovelViewModel load_model(const std::string& path_in, const torch::Device& device, Config* config_out,
                          const Config* config_hint) {
  const std::string path = io::resolve_checkpoint(path_in);
  Config config = config_hint ? *config_hint : Config{};
  io::NamedTensors weights;
  std::map<std::string, std::string> meta;
  if (!io::looks_like_torch_file(path)) io::read_safetensors_header(path, &meta);
  if (meta.count("format") && meta.at("format") == io::kCheckpointFormat) {
    auto ckpt = io::read_checkpoint(path);
    config = ckpt.config;
    weights = std::move(ckpt.model);
  } else {
    auto w = io::read_pretrained_weights(path);
    if (w.source != io::WeightSource::Uplvsm)
      throw std::runtime_error(
          fmt::format("{}: holds {} weights, not a UP-LVSM model; start a run from them with "
                      "`uplvsm train --init {}` or make a checkpoint with `uplvsm convert --input "
                      "{} --config <config> --output init.safetensors`",
                      path, to_string(w.source), path, path));
    if (!config_hint) {
      config.name = std::filesystem::path(path).stem().string();
      config.model = infer_model_config(w.tensors, config.model);
    }
    weights = std::move(w.tensors);
  }
  validate_config(config, path);
  auto net = make_model(config.model);
  io::load_state_dict(*net, weights, path);
  net->to(device);
  net->eval();
  if (config_out) *config_out = config;
  return net;
}

NovelViewModel load_model_with_config_file(const std::string& path, const std::string& config_hint_path,
                                           const torch::Device& device, Config* config_out) {
  if (config_hint_path.empty()) return load_model(path, device, config_out);
  const Config hint = load_config(config_hint_path);
  return load_model(path, device, config_out, &hint);
}

io::LoadReport load_dinov2_into_tokenizer(NovelViewModelImpl& net, const io::NamedTensors& meta,
                                          const std::string& source) {
  io::LoadOptions options;
  options.skip_prefixes = {"mask_token"};  // only used by DINOv2's masked-image pretraining; deleted officially
  if (net.config.dinov2.qk_norm) options.allow_missing_substrings = {"attn.q_norm.", "attn.k_norm."};
  return io::load_state_dict(*net.tokenizer->dino_vit, meta, source, options);
}

}  // namespace uplvsm::model
