#include "uplvsm/model/pretrained_weights.h"

#include <filesystem>
#include <regex>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"
#include "uplvsm/model/checkpoint_io.h"

namespace uplvsm::model {

std::string to_string(WeightSource source) {
  switch (source) {
    case WeightSource::Uplvsm: return "UP-LVSM";
    case WeightSource::Dinov2Meta: return "DINOv2 (Meta names)";
    case WeightSource::Dinov2HuggingFace: return "DINOv2 (HuggingFace names)";
  }
  return "?";
}

namespace {

bool has_key(const NamedTensors& t, const std::string& key) { return t.count(key) > 0; }

bool any_prefix(const NamedTensors& t, const std::string& prefix) {
  auto it = t.lower_bound(prefix);
  return it != t.end() && it->first.rfind(prefix, 0) == 0;
}

NamedTensors strip_prefix(const NamedTensors& in, const std::string& prefix) {
  for (const auto& [k, v] : in)
    if (k.rfind(prefix, 0) != 0) return in;  // only when every key carries it
  NamedTensors out;
  for (const auto& [k, v] : in) out[k.substr(prefix.size())] = v;
  return out;
}

std::string some_keys(const NamedTensors& t, size_t n = 8) {
  std::string s;
  size_t i = 0;
  for (const auto& [k, v] : t) {
    if (i++ == n) return s + " ...";
    s += " " + k;
  }
  return s;
}

const torch::Tensor& require(const NamedTensors& w, const std::string& key) {
  auto it = w.find(key);
  if (it == w.end()) throw std::runtime_error(fmt::format("weights lack '{}', needed to infer the model size", key));
  return it->second;
}

int64_t count_indexed(const NamedTensors& w, const std::string& prefix) {
  int64_t n = 0;
  while (any_prefix(w, fmt::format("{}{}.", prefix, n))) ++n;
  return n;
}

}  // namespace

NamedTensors dinov2_from_huggingface(const NamedTensors& hf_in, const std::string& source) {
  auto hf = strip_prefix(hf_in, "dinov2.");
  static const std::vector<std::pair<std::regex, std::string>> rules = {
      {std::regex(R"(^embeddings\.cls_token$)"), "cls_token"},
      {std::regex(R"(^embeddings\.mask_token$)"), "mask_token"},
      {std::regex(R"(^embeddings\.register_tokens$)"), "register_tokens"},
      {std::regex(R"(^embeddings\.position_embeddings$)"), "pos_embed"},
      {std::regex(R"(^embeddings\.patch_embeddings\.projection\.(weight|bias)$)"), "patch_embed.proj.$1"},
      {std::regex(R"(^encoder\.layer\.(\d+)\.norm([12])\.(weight|bias)$)"), "blocks.$1.norm$2.$3"},
      {std::regex(R"(^encoder\.layer\.(\d+)\.attention\.output\.dense\.(weight|bias)$)"), "blocks.$1.attn.proj.$2"},
      {std::regex(R"(^encoder\.layer\.(\d+)\.layer_scale([12])\.lambda1$)"), "blocks.$1.ls$2.gamma"},
      {std::regex(R"(^encoder\.layer\.(\d+)\.mlp\.(fc[12])\.(weight|bias)$)"), "blocks.$1.mlp.$2.$3"},
      {std::regex(R"(^layernorm\.(weight|bias)$)"), "norm.$1"}};
  static const std::regex qkv(R"(^encoder\.layer\.(\d+)\.attention\.attention\.(query|key|value)\.(weight|bias)$)");
  NamedTensors out;
  std::vector<std::string> unknown;
  std::map<std::string, std::map<std::string, torch::Tensor>> qkv_parts;  // "blocks.i.attn.qkv.weight" -> q/k/v
  for (const auto& [key, value] : hf) {
    std::smatch m;
    if (std::regex_match(key, m, qkv)) {
      qkv_parts[fmt::format("blocks.{}.attn.qkv.{}", m[1].str(), m[3].str())][m[2].str()] = value;
      continue;
    }
    bool mapped = false;
    for (const auto& [pattern, replacement] : rules)
      if (std::regex_match(key, pattern)) {
        out[std::regex_replace(key, pattern, replacement)] = value;
        mapped = true;
        break;
      }
    if (!mapped) unknown.push_back(key);
  }
  if (!unknown.empty())
    throw std::runtime_error(fmt::format("{}: {} HuggingFace DINOv2 keys have no Meta equivalent, e.g. '{}' (SwiGLU "
                                         "ViT-g weights are not supported)",
                                         source, unknown.size(), unknown.front()));
  for (auto& [name, parts] : qkv_parts) {
    for (const char* p : {"query", "key", "value"})
      if (!parts.count(p)) throw std::runtime_error(fmt::format("{}: {} lacks its '{}' part", source, name, p));
    // Meta's fused qkv stacks the rows as [q; k; v].
    out[name] = torch::cat({parts.at("query"), parts.at("key"), parts.at("value")}, 0);
  }
  return out;
}

NamedTensors read_weight_file(const std::string& path, std::string* container, std::string* found_at) {
  if (!std::filesystem::is_regular_file(path))
    throw std::runtime_error(fmt::format("weights {}: no such file", path));
  std::string kind, where;
  NamedTensors raw;
  if (io::looks_like_torch_file(path)) {
    raw = io::read_torch_state_dict(path, &where);
    kind = io::TorchFile(path).format() == "zip" ? "torch zip" : "torch legacy";
  } else {
    std::map<std::string, std::string> meta;
    io::read_safetensors_header(path, &meta);
    if (meta.count("format") && meta.at("format") == kCheckpointFormat) {
      kind = "uplvsm checkpoint";
      raw = read_checkpoint(path).model;
    } else {
      kind = "safetensors";
      raw = io::read_safetensors(path).tensors;
    }
  }
  if (container) *container = kind;
  if (found_at) *found_at = where;
  return raw;
}

PretrainedWeights read_pretrained_weights(const std::string& path) {
  PretrainedWeights w;
  w.path = path;
  NamedTensors raw = read_weight_file(path, &w.container, &w.found_at);
  raw = strip_prefix(raw, "module.");  // DistributedDataParallel wrapping
  // UP-LVSM, or the official posedTargetLVSM layout of the posed variants (same model family, same loader).
  if (has_key(raw, "n_light_field_latent") || has_key(raw, "transformer_input_layernorm.weight")) {
    w.source = WeightSource::Uplvsm;
    w.tensors = std::move(raw);
  } else if (has_key(raw, "cls_token") && any_prefix(raw, "blocks.")) {
    w.source = WeightSource::Dinov2Meta;
    w.tensors = std::move(raw);
  } else if (any_prefix(raw, "embeddings.") || any_prefix(raw, "dinov2.embeddings.")) {
    w.source = WeightSource::Dinov2HuggingFace;
    w.tensors = dinov2_from_huggingface(raw, path);
  } else {
    throw std::runtime_error(fmt::format("weights {}: not UP-LVSM (no 'n_light_field_latent') nor DINOv2 (no "
                                         "'cls_token'/'embeddings.*'); keys:{}",
                                         path, some_keys(raw)));
  }
  return w;
}

ModelConfig infer_model_config(const NamedTensors& w, ModelConfig c) {
  auto& t = c.transformer;
  if (!has_key(w, "n_light_field_latent") && has_key(w, "transformer_input_layernorm.weight")) {
    // The official posedTargetLVSM layout (decoder-only). Its keys do not tell PT-LVSM from our LVSM variant (which
    // poses every input view); the official release is PT-LVSM, so that is the default.
    if (c.variant == "uplvsm") c.variant = "ptlvsm";
    c.pose_mapper = false;
    t.d = require(w, "transformer_input_layernorm.weight").size(0);
    t.d_head = require(w, "transformer_blocks.0.attn.q_norm.weight").size(0);
    t.n_layer = count_indexed(w, "transformer_blocks.");
  } else {
    const auto& latents = require(w, "n_light_field_latent");
    c.variant = "uplvsm";
    c.pose_mapper = has_key(w, "pose_mapper.A");
    t.n_latent_vectors = latents.size(0);
    t.d = latents.size(1);
    t.d_head = require(w, "transformer_encoder.0.attn.q_norm.weight").size(0);
    t.encoder_n_layer = count_indexed(w, "transformer_encoder.");
    t.decoder_n_layer = count_indexed(w, "transformer_decoder.");
    t.estimator_n_layer = count_indexed(w, "estimator.transformer_estimator.");
  }
  const auto& pose = require(w, "target_pose_tokenizer.1.weight");  // [d, 6 p^2]
  c.patch_size = int64_t(std::lround(std::sqrt(double(pose.size(1)) / 6.0)));
  if (6 * c.patch_size * c.patch_size != pose.size(1))
    throw std::runtime_error(fmt::format("target_pose_tokenizer.1.weight has {} inputs, not 6 p^2", pose.size(1)));

  const std::string vit = "image_tokenizer.1.dino_vit.";
  auto& dino = c.dinov2;
  dino.embed_dim = require(w, vit + "cls_token").size(2);
  dino.depth = count_indexed(w, vit + "blocks.");
  dino.mlp_ratio = require(w, vit + "blocks.0.mlp.fc1.weight").size(0) / dino.embed_dim;
  dino.qk_norm = has_key(w, vit + "blocks.0.attn.q_norm.weight");
  if (dino.qk_norm) dino.num_heads = dino.embed_dim / w.at(vit + "blocks.0.attn.q_norm.weight").size(0);
  else if (dino.embed_dim % 64 == 0) dino.num_heads = dino.embed_dim / 64;  // Meta's ViTs all use 64-wide heads
  dino.num_register_tokens = has_key(w, vit + "register_tokens") ? w.at(vit + "register_tokens").size(1) : 0;
  const int64_t positions = require(w, vit + "pos_embed").size(1) - 1;
  dino.pos_grid = int64_t(std::lround(std::sqrt(double(positions))));
  if (dino.pos_grid * dino.pos_grid != positions)
    throw std::runtime_error(fmt::format("{}pos_embed covers {} patches, not a square grid", vit, positions));
  return c;
}

LoadReport load_dinov2_into_uplvsm(UPLVSMImpl& net, const NamedTensors& meta, const std::string& source) {
  LoadOptions options;
  options.skip_prefixes = {"mask_token"};  // only used by DINOv2's masked-image pretraining; deleted officially
  if (net.config.dinov2.qk_norm) options.allow_missing_substrings = {"attn.q_norm.", "attn.k_norm."};
  return load_state_dict(*net.tokenizer->dino_vit, meta, source, options);
}

UPLVSM load_model(const std::string& path_in, const torch::Device& device, Config* config_out,
                  const Config* config_hint) {
  const std::string path = resolve_checkpoint(path_in);
  Config config = config_hint ? *config_hint : Config{};
  NamedTensors weights;
  std::map<std::string, std::string> meta;
  if (!io::looks_like_torch_file(path)) io::read_safetensors_header(path, &meta);
  if (meta.count("format") && meta.at("format") == kCheckpointFormat) {
    auto ckpt = read_checkpoint(path);
    config = ckpt.config;
    weights = std::move(ckpt.model);
  } else {
    auto w = read_pretrained_weights(path);
    if (w.source != WeightSource::Uplvsm)
      throw std::runtime_error(fmt::format("{}: holds {} weights, not a UP-LVSM model; start a run from them with "
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
  UPLVSM net(config.model);
  load_state_dict(*net, weights, path);
  net->to(device);
  net->eval();
  if (config_out) *config_out = config;
  return net;
}

}  // namespace uplvsm::model
