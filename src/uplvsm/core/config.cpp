#include "uplvsm/core/config.h"

#include <algorithm>
#include <array>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "uplvsm/core/json_input.h"
#include "uplvsm/core/retired_keys.h"

namespace uplvsm {

using nlohmann::json;

namespace {

constexpr std::array<const char*, 3> kVariantNames{"uplvsm", "ptlvsm", "lvsm"};
constexpr std::array<const char*, 2> kAmpNames{"none", "bf16"};
constexpr std::array<const char*, 4> kTargetPoseNames{"auto", "estimator", "mapper", "dataset"};

template <typename E, size_t N>
E parse_choice(const std::string& name, const std::string& field, const std::array<const char*, N>& names) {
  std::string expected;
  for (size_t i = 0; i < N; ++i) {
    if (name == names[i]) return static_cast<E>(i);
    expected += fmt::format("{}'{}'", i == 0 ? "" : i + 1 == N ? " or " : ", ", names[i]);
  }
  throw std::runtime_error(fmt::format("{} must be {}, got '{}'", field, expected, name));
}

// The JSON form of a field: enums by name, everything else as it is.
json json_value(Variant v) { return to_string(v); }
json json_value(Amp a) { return to_string(a); }
json json_value(TargetPoses t) { return to_string(t); }
template <typename T>
json json_value(const T& v) {
  return v;
}

// Reads known fields of one JSON object and rejects the rest (retired keys at their old default aside), naming the
// offending path: `source` (the file) and `section` ("training", "model.transformer"; "" at the top).
class Reader {
 public:
  Reader(const json& j, const std::string& source, std::string section = "")
      : j_(j), path_(section.empty() ? source : source + ": " + section), section_(std::move(section)) {
    if (!j_.is_object()) throw std::runtime_error(fmt::format("{}: expected a JSON object", path_));
  }
  template <typename T>
  void get(const char* key, T& out) {
    seen_.insert(key);
    if (!j_.contains(key)) return;
    try {
      if constexpr (std::is_same_v<T, int64_t>)
        out = json_integer(j_.at(key), fmt::format("{}.{}", path_, key));
      else if constexpr (std::is_same_v<T, Variant>)
        out = parse_variant(j_.at(key).get<std::string>(), fmt::format("{}.{}", path_, key));
      else if constexpr (std::is_same_v<T, Amp>)
        out = parse_amp(j_.at(key).get<std::string>(), fmt::format("{}.{}", path_, key));
      else if constexpr (std::is_same_v<T, TargetPoses>)
        out = parse_target_poses(j_.at(key).get<std::string>(), fmt::format("{}.{}", path_, key));
      else
        out = j_.at(key).get<T>();
    } catch (const json::exception& e) {
      throw std::runtime_error(fmt::format("{}.{}: wrong type ({})", path_, key, e.what()));
    }
  }
  const json* child(const char* key) {
    seen_.insert(key);
    return j_.contains(key) ? &j_.at(key) : nullptr;
  }
  void finish() const {
    for (const auto& [k, v] : j_.items())
      if (!seen_.count(k) && !accept_retired_key(section_, k, v, path_))
        throw std::runtime_error(fmt::format("{}: unknown field '{}'", path_, k));
  }

 private:
  const json& j_;
  std::string path_, section_;
  std::set<std::string> seen_;
};

// One list of fields per section, used both to read (with unknown-field checks) and to write JSON.
template <typename C, typename F>
void transformer_fields(C& c, F&& f) {
  f("d", c.d);
  f("d_head", c.d_head);
  f("encoder_n_layer", c.encoder_n_layer);
  f("estimator_n_layer", c.estimator_n_layer);
  f("decoder_n_layer", c.decoder_n_layer);
  f("n_layer", c.n_layer);
  f("n_latent_vectors", c.n_latent_vectors);
  f("qk_norm_eps", c.qk_norm_eps);
  f("special_init", c.special_init);
  f("depth_init", c.depth_init);
  f("rotation_only_latent_camera", c.rotation_only_latent_camera);
}

template <typename C, typename F>
void dinov2_fields(C& c, F&& f) {
  f("embed_dim", c.embed_dim);
  f("depth", c.depth);
  f("num_heads", c.num_heads);
  f("mlp_ratio", c.mlp_ratio);
  f("num_register_tokens", c.num_register_tokens);
  f("qk_norm", c.qk_norm);
  f("qk_norm_eps", c.qk_norm_eps);
  f("pos_grid", c.pos_grid);
  f("interpolate_antialias", c.interpolate_antialias);
  f("interpolate_offset", c.interpolate_offset);
  f("layerscale_init", c.layerscale_init);
  f("imagenet_normalize", c.imagenet_normalize);
  f("pos_embed_init", c.pos_embed_init);
}

template <typename C, typename F>
void model_fields(C& c, F&& f) {
  f("variant", c.variant);
  f("pose_mapper", c.pose_mapper);
  f("keep_image_tokens", c.keep_image_tokens);
  f("encoder_latent_cameras", c.encoder_latent_cameras);
  f("image_size", c.image_size);
  f("patch_size", c.patch_size);
}

template <typename C, typename F>
void training_fields(C& c, F&& f) {
  f("lr", c.lr);
  f("beta1", c.beta1);
  f("beta2", c.beta2);
  f("eps", c.eps);
  f("weight_decay", c.weight_decay);
  f("warmup", c.warmup);
  f("train_steps", c.train_steps);
  f("grad_clip_norm", c.grad_clip_norm);
  f("allowed_gradnorm_factor", c.allowed_gradnorm_factor);
  f("batch_size", c.batch_size);
  f("grad_accum_steps", c.grad_accum_steps);
  f("global_batch_size", c.global_batch_size);
  f("grad_checkpoint_every", c.grad_checkpoint_every);
  f("num_views", c.num_views);
  f("num_input_views", c.num_input_views);
  f("num_target_views", c.num_target_views);
  f("min_frame_dist", c.min_frame_dist);
  f("max_frame_dist", c.max_frame_dist);
  f("frame_dist_curriculum_steps", c.frame_dist_curriculum_steps);
  f("l2_loss_weight", c.l2_loss_weight);
  f("perceptual_loss_weight", c.perceptual_loss_weight);
  f("gradient_difference_weight", c.gradient_difference_weight);
  f("random_tokenizer", c.random_tokenizer);
  f("checkpoint_every", c.checkpoint_every);
  f("keep_checkpoints", c.keep_checkpoints);
  f("log_every", c.log_every);
  f("eval_every", c.eval_every);
  f("seed", c.seed);
  f("loader_threads", c.loader_threads);
  f("amp", c.amp);
  f("tf32", c.tf32);
  f("target_poses", c.target_poses);
  f("max_train_scenes", c.max_train_scenes);
  f("chunks_per_shuffle", c.chunks_per_shuffle);
  f("subset", c.subset);
  f("pose_noise_std", c.pose_noise_std);
  f("view_sampler", c.view_sampler);
}

template <typename C, typename F>
void dataset_fields(C& c, F&& f) {
  f("kind", c.kind);
  f("square_crop", c.square_crop);
  f("num_train_scenes", c.num_train_scenes);
  f("num_test_scenes", c.num_test_scenes);
  f("frames_per_scene", c.frames_per_scene);
  f("render_height", c.render_height);
  f("render_width", c.render_width);
  f("frame_spacing", c.frame_spacing);
  f("texture_scale", c.texture_scale);
  f("eval_gap", c.eval_gap);
  f("seed", c.seed);
}

template <typename C, typename F>
void eval_fields(C& c, F&& f) {
  f("max_scenes", c.max_scenes);
}

// Reads one flat section; `children` reads nested sections before the unknown-field check.
template <typename C, typename Fields, typename Children>
void read_section(const json& j, const std::string& source, const std::string& section, C& c, Fields fields,
                  Children children) {
  Reader r(j, source, section);
  fields(c, [&](const char* key, auto& member) { r.get(key, member); });
  children(r);
  r.finish();
}

template <typename C, typename Fields>
void read_section(const json& j, const std::string& source, const std::string& section, C& c, Fields fields) {
  read_section(j, source, section, c, fields, [](Reader&) {});
}

template <typename C, typename Fields>
json write_section(const C& c, Fields fields) {
  json out = json::object();
  fields(c, [&](const char* key, const auto& member) { out[key] = json_value(member); });
  return out;
}

#define UPLVSM_FIELDS(fn) [](auto& c, auto&& f) { fn(c, f); }

}  // namespace

std::string to_string(Variant v) { return kVariantNames.at(static_cast<size_t>(v)); }
std::string to_string(Amp a) { return kAmpNames.at(static_cast<size_t>(a)); }
std::string to_string(TargetPoses t) { return kTargetPoseNames.at(static_cast<size_t>(t)); }

Variant parse_variant(const std::string& name, const std::string& field) {
  return parse_choice<Variant>(name, field, kVariantNames);
}
Amp parse_amp(const std::string& name, const std::string& field) { return parse_choice<Amp>(name, field, kAmpNames); }
TargetPoses parse_target_poses(const std::string& name, const std::string& field) {
  return parse_choice<TargetPoses>(name, field, kTargetPoseNames);
}

Config config_from_json(const json& j, const std::string& source) {
  Config c;
  Reader r(j, source);
  r.get("name", c.name);
  if (auto m = r.child("model"))
    read_section(*m, source, "model", c.model, UPLVSM_FIELDS(model_fields), [&](Reader& mr) {
      if (auto t = mr.child("transformer"))
        read_section(*t, source, "model.transformer", c.model.transformer, UPLVSM_FIELDS(transformer_fields));
      if (auto d = mr.child("dinov2"))
        read_section(*d, source, "model.dinov2", c.model.dinov2, UPLVSM_FIELDS(dinov2_fields));
    });
  if (auto t = r.child("training")) read_section(*t, source, "training", c.training, UPLVSM_FIELDS(training_fields));
  if (auto d = r.child("dataset")) read_section(*d, source, "dataset", c.dataset, UPLVSM_FIELDS(dataset_fields));
  if (auto e = r.child("eval")) read_section(*e, source, "eval", c.eval, UPLVSM_FIELDS(eval_fields));
  r.finish();
  validate_config(c, source);
  return c;
}

Config apply_config_overrides(const Config& c, const std::vector<std::string>& assignments, const std::string& source) {
  if (assignments.empty()) return c;
  json j = config_to_json(c);
  for (const auto& a : assignments) {
    const auto eq = a.find('=');
    if (eq == std::string::npos || eq == 0)
      throw std::runtime_error(fmt::format("--set '{}': expected section.field=value (e.g. training.lr=3e-4)", a));
    const std::string path = a.substr(0, eq), text = a.substr(eq + 1);
    json* node = &j;
    for (size_t start = 0;;) {
      const size_t dot = path.find('.', start);
      const std::string key = path.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
      if (!node->is_object() || !node->contains(key)) {
        const auto* retired =
            dot == std::string::npos ? find_retired_key(path.substr(0, start ? start - 1 : 0), key) : nullptr;
        throw std::runtime_error(fmt::format("--set '{}': the config has no field '{}'{}", a, path,
                                             retired ? "; " + retired_key_note(*retired) : ""));
      }
      node = &(*node)[key];
      if (dot == std::string::npos) break;
      start = dot + 1;
    }
    if (node->is_object()) throw std::runtime_error(fmt::format("--set '{}': '{}' is a section, not a field", a, path));
    // JSON values (numbers, true/false, quoted strings) as written; anything else is a string (auto, bf16, ...).
    json value = json::parse(text, nullptr, /*allow_exceptions=*/false);
    *node = value.is_discarded() ? json(text) : value;
  }
  return config_from_json(j, source + " (with --set)");
}

namespace {

json read_config_object(const std::string& path) {
  json j = read_json_file(path, "config");
  if (!j.is_object()) throw std::runtime_error(fmt::format("config {}: expected a JSON object", path));
  return j;
}

// `over` written onto `base`: objects merged key by key, any other value replaced.
void merge_into(json& base, const json& over) {
  for (const auto& [key, value] : over.items())
    if (value.is_object() && base.contains(key) && base[key].is_object())
      merge_into(base[key], value);
    else
      base[key] = value;
}

constexpr size_t kMaxExtendsDepth = 8;
constexpr uintmax_t kMaxConfigBytes = 1 << 20;

// The file's JSON with its "extends" chain resolved; `chain` holds the files being read (a cycle is an error).
json resolved_json(const std::string& path, std::vector<std::string>& chain) {
  json j = read_config_object(path);
  if (!j.contains("extends")) return j;
  const auto& extends = j["extends"];
  if (!extends.is_string() || extends.get<std::string>().empty())
    throw std::runtime_error(fmt::format("config {}: 'extends' must be a config file name (relative to {})", path,
                                         std::filesystem::path(path).parent_path().string()));
  const auto base_path = (std::filesystem::path(path).parent_path() / extends.get<std::string>()).string();
  const auto canonical = std::filesystem::weakly_canonical(base_path).string();
  if (std::find(chain.begin(), chain.end(), canonical) != chain.end() || chain.size() >= kMaxExtendsDepth)
    throw std::runtime_error(fmt::format("config {}: 'extends' {} makes a cycle or a chain over {} files", path,
                                         base_path, kMaxExtendsDepth));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(base_path, ec) || std::filesystem::file_size(base_path, ec) > kMaxConfigBytes)
    throw std::runtime_error(
        fmt::format("config {}: 'extends' {} is not a config file (a regular file under 1 MB)", path, base_path));
  chain.push_back(canonical);
  json merged = resolved_json(base_path, chain);
  merged.erase("name");  // a name says which file this is: never inherited
  j.erase("extends");
  merge_into(merged, j);
  return merged;
}

}  // namespace

Config load_config(const std::string& path) {
  std::vector<std::string> chain{std::filesystem::weakly_canonical(path).string()};
  json j = resolved_json(path, chain);
  if (!j.contains("name")) j["name"] = std::filesystem::path(path).stem().string();
  return config_from_json(j, path);
}

json config_to_json(const Config& c) {
  json model = write_section(c.model, UPLVSM_FIELDS(model_fields));
  model["transformer"] = write_section(c.model.transformer, UPLVSM_FIELDS(transformer_fields));
  model["dinov2"] = write_section(c.model.dinov2, UPLVSM_FIELDS(dinov2_fields));
  return json{{"name", c.name},
              {"model", model},
              {"training", write_section(c.training, UPLVSM_FIELDS(training_fields))},
              {"dataset", write_section(c.dataset, UPLVSM_FIELDS(dataset_fields))},
              {"eval", write_section(c.eval, UPLVSM_FIELDS(eval_fields))}};
}

}  // namespace uplvsm
