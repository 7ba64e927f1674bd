#include "uplvsm/core/config.h"

#include <array>
#include <cmath>
#include <fstream>
#include <set>
#include <stdexcept>
#include <type_traits>

#include <fmt/format.h>

#include "uplvsm/core/json_input.h"

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
json json_value(TargetPoseChoice t) { return to_string(t); }
template <typename T>
json json_value(const T& v) {
  return v;
}

// Reads known fields of one JSON object and rejects the rest, naming the offending path.
class Reader {
 public:
  Reader(const json& j, std::string path) : j_(j), path_(std::move(path)) {
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
      else if constexpr (std::is_same_v<T, TargetPoseChoice>)
        out = parse_target_pose_choice(j_.at(key).get<std::string>(), fmt::format("{}.{}", path_, key));
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
      if (!seen_.count(k)) throw std::runtime_error(fmt::format("{}: unknown field '{}'", path_, k));
  }

 private:
  const json& j_;
  std::string path_;
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
  f("identity_rotation_init", c.identity_rotation_init);
  f("rotation_only_latent_camera", c.rotation_only_latent_camera);
  f("latent_rotation_gain", c.latent_rotation_gain);
  f("estimator_correspondence", c.estimator_correspondence);
  f("pose_error_feedback_steps", c.pose_error_feedback_steps);
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
  f("encoder_cameras", c.encoder_cameras);
  f("keep_image_tokens", c.keep_image_tokens);
  f("estimator_half_view", c.estimator_half_view);
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
  f("grad_checkpoint_every", c.grad_checkpoint_every);
  f("num_views", c.num_views);
  f("num_input_views", c.num_input_views);
  f("num_target_views", c.num_target_views);
  f("min_frame_dist", c.min_frame_dist);
  f("max_frame_dist", c.max_frame_dist);
  f("frame_dist_curriculum_steps", c.frame_dist_curriculum_steps);
  f("l2_loss_weight", c.l2_loss_weight);
  f("perceptual_loss_weight", c.perceptual_loss_weight);
  f("l1_loss_weight", c.l1_loss_weight);
  f("ssim_loss_weight", c.ssim_loss_weight);
  f("gradient_difference_weight", c.gradient_difference_weight);
  f("checkpoint_every", c.checkpoint_every);
  f("keep_checkpoints", c.keep_checkpoints);
  f("log_every", c.log_every);
  f("eval_every", c.eval_every);
  f("seed", c.seed);
  f("loader_threads", c.loader_threads);
  f("amp", c.amp);
  f("target_poses", c.target_poses);
  f("max_train_scenes", c.max_train_scenes);
  f("subset", c.subset);
  f("pose_noise_variance", c.pose_noise_variance);
  f("view_sampler", c.view_sampler);
  f("rotation_equivariance_weight", c.rotation_equivariance_weight);
  f("rotation_equivariance_degrees", c.rotation_equivariance_degrees);
  f("turned_view_weight", c.turned_view_weight);
  f("turned_view_degrees", c.turned_view_degrees);
  f("rotation_alignment_weight", c.rotation_alignment_weight);
  f("rotation_alignment_blur", c.rotation_alignment_blur);
  f("latent_translation_warmup_steps", c.latent_translation_warmup_steps);
  f("latent_translation_weight", c.latent_translation_weight);
  f("init_new_blocks_identity", c.init_new_blocks_identity);
  f("fitted_pose_steps", c.fitted_pose_steps);
  f("fitted_pose_lr", c.fitted_pose_lr);
  f("fitted_pose_weight", c.fitted_pose_weight);
  f("render_at_fitted_poses", c.render_at_fitted_poses);
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
  f("num_target_views", c.num_target_views);
  f("max_scenes", c.max_scenes);
}

// Reads one flat section; `children` reads nested sections before the unknown-field check.
template <typename C, typename Fields, typename Children>
void read_section(const json& j, const std::string& path, C& c, Fields fields, Children children) {
  Reader r(j, path);
  fields(c, [&](const char* key, auto& member) { r.get(key, member); });
  children(r);
  r.finish();
}

template <typename C, typename Fields>
void read_section(const json& j, const std::string& path, C& c, Fields fields) {
  read_section(j, path, c, fields, [](Reader&) {});
}

template <typename C, typename Fields>
json write_section(const C& c, Fields fields) {
  json out = json::object();
  fields(c, [&](const char* key, const auto& member) { out[key] = json_value(member); });
  return out;
}

#define UPLVSM_FIELDS(fn) [](auto& c, auto&& f) { fn(c, f); }

void require(bool ok, const std::string& source, const std::string& what) {
  if (!ok) throw std::runtime_error(fmt::format("{}: {}", source, what));
}

}  // namespace

std::string to_string(Variant v) { return kVariantNames.at(static_cast<size_t>(v)); }
std::string to_string(Amp a) { return kAmpNames.at(static_cast<size_t>(a)); }
std::string to_string(TargetPoseChoice t) { return kTargetPoseNames.at(static_cast<size_t>(t)); }

Variant parse_variant(const std::string& name, const std::string& field) {
  return parse_choice<Variant>(name, field, kVariantNames);
}
Amp parse_amp(const std::string& name, const std::string& field) { return parse_choice<Amp>(name, field, kAmpNames); }
TargetPoseChoice parse_target_pose_choice(const std::string& name, const std::string& field) {
  return parse_choice<TargetPoseChoice>(name, field, kTargetPoseNames);
}

Config config_from_json(const json& j, const std::string& source) {
  Config c;
  Reader r(j, source);
  r.get("name", c.name);
  if (auto m = r.child("model"))
    read_section(*m, source + ": model", c.model, UPLVSM_FIELDS(model_fields), [&](Reader& mr) {
      if (auto t = mr.child("transformer"))
        read_section(*t, source + ": model.transformer", c.model.transformer, UPLVSM_FIELDS(transformer_fields));
      if (auto d = mr.child("dinov2"))
        read_section(*d, source + ": model.dinov2", c.model.dinov2, UPLVSM_FIELDS(dinov2_fields));
    });
  if (auto t = r.child("training")) read_section(*t, source + ": training", c.training, UPLVSM_FIELDS(training_fields));
  if (auto d = r.child("dataset")) read_section(*d, source + ": dataset", c.dataset, UPLVSM_FIELDS(dataset_fields));
  if (auto e = r.child("eval")) read_section(*e, source + ": eval", c.eval, UPLVSM_FIELDS(eval_fields));
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
      if (!node->is_object() || !node->contains(key))
        throw std::runtime_error(fmt::format("--set '{}': the config has no field '{}'", a, path));
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

Config load_config(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("config {}: cannot open file", path));
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    throw std::runtime_error(fmt::format("config {}: invalid JSON ({})", path, e.what()));
  }
  return config_from_json(j, path);
}

namespace {

void validate_model(const ModelConfig& m, const std::string& s) {
  const auto& t = m.transformer;
  require(!m.pose_mapper || m.variant == Variant::UPLVSM, s,
          "model.pose_mapper: only the uplvsm variant has latent poses to map to");
  require(!m.transformer.estimator_correspondence || (m.variant == Variant::UPLVSM && m.keep_image_tokens), s,
          "model.transformer.estimator_correspondence reads input view 0's image tokens: it needs the uplvsm variant "
          "and model.keep_image_tokens: true");
  require(t.pose_error_feedback_steps == 0 || (m.variant == Variant::UPLVSM && !m.estimator_half_view), s,
          "model.transformer.pose_error_feedback_steps corrects the estimator's latent poses from the whole target: it "
          "needs the uplvsm variant without model.estimator_half_view");
  require(t.pose_error_feedback_steps >= 0 && t.pose_error_feedback_steps <= 8, s,
          fmt::format("model.transformer.pose_error_feedback_steps must be in [0, 8], got {}",
                      t.pose_error_feedback_steps));
  require(!m.keep_image_tokens || m.variant == Variant::UPLVSM, s,
          "model.keep_image_tokens: only the uplvsm variant has an encoder whose image tokens it could keep");
  require(m.patch_size > 0 && m.image_size > 0 && m.image_size % m.patch_size == 0, s,
          fmt::format("model.image_size ({}) must be a positive multiple of model.patch_size ({})", m.image_size,
                      m.patch_size));
  require(t.d > 0 && t.d_head > 0 && t.d % t.d_head == 0, s,
          fmt::format("model.transformer.d ({}) must be a multiple of d_head ({})", t.d, t.d_head));
  require(t.encoder_n_layer >= 1 && t.estimator_n_layer >= 1 && t.decoder_n_layer >= 1 && t.n_layer >= 1, s,
          "model.transformer: every stack needs at least one layer");
  require(t.n_latent_vectors >= 1, s, "model.transformer.n_latent_vectors must be >= 1");
  require(std::isfinite(t.latent_rotation_gain) && t.latent_rotation_gain > 0, s,
          "model.transformer.latent_rotation_gain must be a finite number > 0");
  require(m.dinov2.embed_dim == t.d, s,
          fmt::format("model.dinov2.embed_dim ({}) must equal model.transformer.d ({}): DINOv2 tokens are used "
                      "directly as transformer tokens",
                      m.dinov2.embed_dim, t.d));
  require(m.dinov2.num_heads > 0 && m.dinov2.embed_dim % m.dinov2.num_heads == 0, s,
          "model.dinov2.embed_dim must be a multiple of num_heads");
  require(m.dinov2.pos_embed_init == "normal" || m.dinov2.pos_embed_init == "sincos", s,
          "model.dinov2.pos_embed_init must be 'normal' or 'sincos', got '" + m.dinov2.pos_embed_init + "'");
  require(m.dinov2.pos_embed_init != "sincos" || m.dinov2.embed_dim % 4 == 0, s,
          "model.dinov2.pos_embed_init 'sincos' needs embed_dim divisible by 4");
}

// Whether UP-LVSM's estimator supplies the training targets' latent poses (what the latent-pose terms act on).
bool estimates_target_poses(const ModelConfig& m, const TrainingConfig& tr) {
  return m.variant == Variant::UPLVSM &&
         (tr.target_poses == TargetPoseChoice::Auto || tr.target_poses == TargetPoseChoice::Estimator);
}

// Where the target cameras come from, against what the model can do with them.
void validate_target_poses(const ModelConfig& m, const TrainingConfig& tr, const std::string& s) {
  const auto tp = tr.target_poses;
  require(m.variant == Variant::UPLVSM || tp == TargetPoseChoice::Auto || tp == TargetPoseChoice::Dataset, s,
          "training.target_poses: the " + to_string(m.variant) +
              " variant renders from dataset cameras ('auto' or 'dataset')");
  require(tp != TargetPoseChoice::Mapper || m.pose_mapper, s,
          "training.target_poses 'mapper' needs model.pose_mapper: true");
  require(!m.encoder_cameras || (m.variant == Variant::UPLVSM && tp == TargetPoseChoice::Dataset), s,
          "model.encoder_cameras (the encoder reads real input cameras) needs the uplvsm variant and "
          "training.target_poses 'dataset'");
  require(!m.estimator_half_view || m.variant == Variant::UPLVSM, s,
          "model.estimator_half_view: only the uplvsm variant has an estimator to show half a view");
  require(!m.estimator_half_view || !estimates_target_poses(m, tr) ||
              (tr.perceptual_loss_weight == 0 && tr.l1_loss_weight == 0 && tr.ssim_loss_weight == 0 &&
               tr.gradient_difference_weight == 0),
          s,
          "model.estimator_half_view: training scores half of each target with the MSE alone; set "
          "training.perceptual_loss_weight, l1_loss_weight, ssim_loss_weight and gradient_difference_weight to 0");
  require(!m.encoder_latent_cameras || (m.variant == Variant::UPLVSM && !m.encoder_cameras), s,
          "model.encoder_latent_cameras: only the uplvsm variant without model.encoder_cameras has latent cameras "
          "to give its encoder");
}

// The training terms on latent poses (not in the paper): their ranges, and only where the estimator supplies them.
void validate_latent_pose_terms(const ModelConfig& m, const TrainingConfig& tr, const std::string& s) {
  const bool estimated_poses = estimates_target_poses(m, tr);
  auto only_with_estimated_poses = [&](bool used, const std::string& field, const std::string& what) {
    require(!used || estimated_poses, s,
            field + ": only a UP-LVSM whose target poses come from its estimator has " + what);
  };
  require(tr.rotation_equivariance_weight >= 0 && tr.rotation_equivariance_degrees > 0 &&
              tr.rotation_equivariance_degrees <= 30,
          s, "training.rotation_equivariance_weight must be >= 0 and rotation_equivariance_degrees in (0, 30]");
  only_with_estimated_poses(tr.rotation_equivariance_weight != 0, "training.rotation_equivariance_weight",
                            "latent poses to make equivariant");
  require(tr.turned_view_weight >= 0 && std::isfinite(tr.turned_view_weight) && tr.turned_view_degrees > 0 &&
              tr.turned_view_degrees <= 30,
          s, "training.turned_view_weight must be a finite number >= 0 and turned_view_degrees in (0, 30]");
  only_with_estimated_poses(tr.turned_view_weight != 0, "training.turned_view_weight", "latent poses to turn");
  require(tr.rotation_alignment_weight >= 0 && std::isfinite(tr.rotation_alignment_weight), s,
          "training.rotation_alignment_weight must be a finite number >= 0");
  require(tr.rotation_alignment_blur >= 0 && tr.rotation_alignment_blur <= 64, s,
          "training.rotation_alignment_blur must be a blur in pixels in [0, 64]");
  require(tr.rotation_alignment_blur == 0 || tr.rotation_alignment_weight > 0, s,
          "training.rotation_alignment_blur needs training.rotation_alignment_weight > 0");
  only_with_estimated_poses(tr.rotation_alignment_weight != 0, "training.rotation_alignment_weight",
                            "latent rotations to align");
  require(tr.latent_translation_warmup_steps >= 0, s, "training.latent_translation_warmup_steps must be >= 0");
  require(tr.latent_translation_weight >= 0 && std::isfinite(tr.latent_translation_weight), s,
          "training.latent_translation_weight must be a finite number >= 0");
  only_with_estimated_poses(tr.latent_translation_warmup_steps != 0 || tr.latent_translation_weight != 0,
                            "training.latent_translation_warmup_steps / latent_translation_weight",
                            "a latent translation to warm up or weigh");
  require(tr.fitted_pose_steps >= 0 && tr.fitted_pose_steps <= 1000 && tr.fitted_pose_lr > 0 &&
              std::isfinite(tr.fitted_pose_lr) && tr.fitted_pose_weight >= 0 && std::isfinite(tr.fitted_pose_weight),
          s,
          "training.fitted_pose_steps must be in [0, 1000] (0: off), fitted_pose_lr a finite number > 0 and "
          "fitted_pose_weight a finite number >= 0");
  only_with_estimated_poses(tr.fitted_pose_steps != 0, "training.fitted_pose_steps", "latent poses to fit");
  require(tr.fitted_pose_steps == 0 || !m.estimator_half_view, s,
          "training.fitted_pose_steps: fits each pose to its whole target, which model.estimator_half_view hides "
          "half of; use one or the other");
}

void validate_training(const Config& c, const std::string& s) {
  const auto& tr = c.training;
  require(tr.num_input_views >= 1 && tr.num_target_views >= 1, s, "training: need >= 1 input and target view");
  require(tr.num_views >= tr.num_input_views && tr.num_views >= 2, s,
          "training.num_views must be >= num_input_views and >= 2");
  require(tr.batch_size >= 1 && tr.grad_accum_steps >= 1, s, "training.batch_size and grad_accum_steps must be >= 1");
  require(tr.grad_checkpoint_every >= 0, s, "training.grad_checkpoint_every must be >= 0 (0: off)");
  require(tr.min_frame_dist >= 1 && tr.max_frame_dist >= tr.min_frame_dist, s,
          "training: need 1 <= min_frame_dist <= max_frame_dist");
  require(tr.frame_dist_curriculum_steps >= 0, s, "training.frame_dist_curriculum_steps must be >= 0");
  for (const double w : {tr.l1_loss_weight, tr.ssim_loss_weight, tr.gradient_difference_weight})
    require(w >= 0 && std::isfinite(w), s,
            "training.l1_loss_weight, ssim_loss_weight and gradient_difference_weight must be finite numbers >= 0 "
            "(0: off)");
  require(tr.ssim_loss_weight == 0 || c.model.image_size >= 11, s,
          "training.ssim_loss_weight needs model.image_size >= 11 (SSIM's 11x11 window)");
  require(tr.max_train_scenes >= 0, s, "training.max_train_scenes must be >= 0 (0: every scene of the train split)");
  require(tr.pose_noise_variance >= 0 && std::isfinite(tr.pose_noise_variance), s,
          "training.pose_noise_variance must be a finite number >= 0");
  require(tr.train_steps >= 1 && tr.warmup >= 0, s, "training.train_steps must be >= 1 and warmup >= 0");
  require(c.dataset.frames_per_scene >= tr.num_views, s, "dataset.frames_per_scene must be >= training.num_views");
  require(c.dataset.texture_scale > 0, s, "dataset.texture_scale must be > 0");
  require(tr.view_sampler == "auto" || tr.view_sampler == "ordered" || tr.view_sampler == "unordered", s,
          "training.view_sampler must be 'auto', 'ordered' or 'unordered', got '" + tr.view_sampler + "'");
  require(c.dataset.kind == "rooms" || c.dataset.kind == "objects", s,
          "dataset.kind must be 'rooms' or 'objects', got '" + c.dataset.kind + "'");
}

}  // namespace

void validate_config(const Config& c, const std::string& s) {
  validate_model(c.model, s);
  validate_training(c, s);
  validate_target_poses(c.model, c.training, s);
  validate_latent_pose_terms(c.model, c.training, s);
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
