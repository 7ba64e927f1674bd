#include "uplvsm/io/pretrained_weights.h"

#include <filesystem>
#include <regex>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/io/torch_file.h"

namespace uplvsm::io {

std::string to_string(WeightSource source) {
  switch (source) {
    case WeightSource::Uplvsm: return "UP-LVSM";
    case WeightSource::Dinov2Meta: return "DINOv2 (Meta names)";
    case WeightSource::Dinov2HuggingFace: return "DINOv2 (HuggingFace names)";
  }
  return "?";
}

namespace {

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
    throw std::runtime_error(
        fmt::format("{}: {} HuggingFace DINOv2 keys have no Meta equivalent, e.g. '{}' (SwiGLU "
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
  if (!std::filesystem::is_regular_file(path)) throw std::runtime_error(fmt::format("weights {}: no such file", path));
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
    throw std::runtime_error(
        fmt::format("weights {}: not UP-LVSM (no 'n_light_field_latent') nor DINOv2 (no "
                    "'cls_token'/'embeddings.*'); keys:{}",
                    path, some_keys(raw)));
  }
  return w;
}

}  // namespace uplvsm::io
