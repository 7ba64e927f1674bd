#include "uplvsm/core/config.h"

#include <fstream>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm {

using nlohmann::json;

namespace {

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

void read_transformer(const json& j, const std::string& p, TransformerConfig& c) {
  Reader r(j, p);
  r.get("d", c.d);
  r.get("d_head", c.d_head);
  r.get("encoder_n_layer", c.encoder_n_layer);
  r.get("estimator_n_layer", c.estimator_n_layer);
  r.get("decoder_n_layer", c.decoder_n_layer);
  r.get("n_latent_vectors", c.n_latent_vectors);
  r.get("qk_norm_eps", c.qk_norm_eps);
  r.get("special_init", c.special_init);
  r.get("depth_init", c.depth_init);
  r.finish();
}

void read_dinov2(const json& j, const std::string& p, Dinov2Config& c) {
  Reader r(j, p);
  r.get("embed_dim", c.embed_dim);
  r.get("depth", c.depth);
  r.get("num_heads", c.num_heads);
  r.get("mlp_ratio", c.mlp_ratio);
  r.get("num_register_tokens", c.num_register_tokens);
  r.get("qk_norm", c.qk_norm);
  r.get("qk_norm_eps", c.qk_norm_eps);
  r.get("pos_grid", c.pos_grid);
  r.get("interpolate_antialias", c.interpolate_antialias);
  r.get("interpolate_offset", c.interpolate_offset);
  r.get("layerscale_init", c.layerscale_init);
  r.get("imagenet_normalize", c.imagenet_normalize);
  r.finish();
}

void read_model(const json& j, const std::string& p, ModelConfig& c) {
  Reader r(j, p);
  r.get("variant", c.variant);
  r.get("image_size", c.image_size);
  r.get("patch_size", c.patch_size);
  if (auto t = r.child("transformer")) read_transformer(*t, p + ".transformer", c.transformer);
  if (auto d = r.child("dinov2")) read_dinov2(*d, p + ".dinov2", c.dinov2);
  r.finish();
}

void read_training(const json& j, const std::string& p, TrainingConfig& c) {
  Reader r(j, p);
  r.get("lr", c.lr);
  r.get("beta1", c.beta1);
  r.get("beta2", c.beta2);
  r.get("eps", c.eps);
  r.get("weight_decay", c.weight_decay);
  r.get("warmup", c.warmup);
  r.get("train_steps", c.train_steps);
  r.get("grad_clip_norm", c.grad_clip_norm);
  r.get("allowed_gradnorm_factor", c.allowed_gradnorm_factor);
  r.get("batch_size", c.batch_size);
  r.get("grad_accum_steps", c.grad_accum_steps);
  r.get("num_views", c.num_views);
  r.get("num_input_views", c.num_input_views);
  r.get("num_target_views", c.num_target_views);
  r.get("min_frame_dist", c.min_frame_dist);
  r.get("max_frame_dist", c.max_frame_dist);
  r.get("l2_loss_weight", c.l2_loss_weight);
  r.get("perceptual_loss_weight", c.perceptual_loss_weight);
  r.get("checkpoint_every", c.checkpoint_every);
  r.get("keep_checkpoints", c.keep_checkpoints);
  r.get("log_every", c.log_every);
  r.get("eval_every", c.eval_every);
  r.get("seed", c.seed);
  r.get("loader_threads", c.loader_threads);
  r.get("amp", c.amp);
  r.finish();
}

void read_dataset(const json& j, const std::string& p, DatasetConfig& c) {
  Reader r(j, p);
  r.get("square_crop", c.square_crop);
  r.get("num_train_scenes", c.num_train_scenes);
  r.get("num_test_scenes", c.num_test_scenes);
  r.get("frames_per_scene", c.frames_per_scene);
  r.get("render_height", c.render_height);
  r.get("render_width", c.render_width);
  r.get("frame_spacing", c.frame_spacing);
  r.get("eval_gap", c.eval_gap);
  r.get("seed", c.seed);
  r.finish();
}

void read_eval(const json& j, const std::string& p, EvalConfig& c) {
  Reader r(j, p);
  r.get("num_target_views", c.num_target_views);
  r.get("max_scenes", c.max_scenes);
  r.finish();
}

void require(bool ok, const std::string& source, const std::string& what) {
  if (!ok) throw std::runtime_error(fmt::format("{}: {}", source, what));
}

}  // namespace

Config config_from_json(const json& j, const std::string& source) {
  Config c;
  Reader r(j, source);
  r.get("name", c.name);
  if (auto m = r.child("model")) read_model(*m, source + ": model", c.model);
  if (auto t = r.child("training")) read_training(*t, source + ": training", c.training);
  if (auto d = r.child("dataset")) read_dataset(*d, source + ": dataset", c.dataset);
  if (auto e = r.child("eval")) read_eval(*e, source + ": eval", c.eval);
  r.finish();
  validate_config(c, source);
  return c;
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

void validate_config(const Config& c, const std::string& s) {
  const auto& m = c.model;
  const auto& t = m.transformer;
  require(m.variant == "uplvsm", s, "model.variant: only 'uplvsm' is implemented, got '" + m.variant + "'");
  require(m.patch_size > 0 && m.image_size > 0 && m.image_size % m.patch_size == 0, s,
          fmt::format("model.image_size ({}) must be a positive multiple of model.patch_size ({})", m.image_size,
                      m.patch_size));
  require(t.d > 0 && t.d_head > 0 && t.d % t.d_head == 0, s,
          fmt::format("model.transformer.d ({}) must be a multiple of d_head ({})", t.d, t.d_head));
  require(t.encoder_n_layer >= 1 && t.estimator_n_layer >= 1 && t.decoder_n_layer >= 1, s,
          "model.transformer: every stack needs at least one layer");
  require(t.n_latent_vectors >= 1, s, "model.transformer.n_latent_vectors must be >= 1");
  require(m.dinov2.embed_dim == t.d, s,
          fmt::format("model.dinov2.embed_dim ({}) must equal model.transformer.d ({}): DINOv2 tokens are used "
                      "directly as transformer tokens",
                      m.dinov2.embed_dim, t.d));
  require(m.dinov2.num_heads > 0 && m.dinov2.embed_dim % m.dinov2.num_heads == 0, s,
          "model.dinov2.embed_dim must be a multiple of num_heads");
  const auto& tr = c.training;
  require(tr.num_input_views >= 1 && tr.num_target_views >= 1, s, "training: need >= 1 input and target view");
  require(tr.num_views >= tr.num_input_views && tr.num_views >= 2, s, "training.num_views must be >= num_input_views and >= 2");
  require(tr.batch_size >= 1 && tr.grad_accum_steps >= 1, s, "training.batch_size and grad_accum_steps must be >= 1");
  require(tr.min_frame_dist >= 1 && tr.max_frame_dist >= tr.min_frame_dist, s,
          "training: need 1 <= min_frame_dist <= max_frame_dist");
  require(tr.amp == "none" || tr.amp == "bf16", s, "training.amp must be 'none' or 'bf16'");
  require(tr.train_steps >= 1 && tr.warmup >= 0, s, "training.train_steps must be >= 1 and warmup >= 0");
  require(c.dataset.frames_per_scene >= tr.num_views, s, "dataset.frames_per_scene must be >= training.num_views");
}

json config_to_json(const Config& c) {
  const auto& t = c.model.transformer;
  const auto& d = c.model.dinov2;
  const auto& tr = c.training;
  const auto& ds = c.dataset;
  return json{
      {"name", c.name},
      {"model",
       {{"variant", c.model.variant},
        {"image_size", c.model.image_size},
        {"patch_size", c.model.patch_size},
        {"transformer",
         {{"d", t.d}, {"d_head", t.d_head}, {"encoder_n_layer", t.encoder_n_layer},
          {"estimator_n_layer", t.estimator_n_layer}, {"decoder_n_layer", t.decoder_n_layer},
          {"n_latent_vectors", t.n_latent_vectors}, {"qk_norm_eps", t.qk_norm_eps},
          {"special_init", t.special_init}, {"depth_init", t.depth_init}}},
        {"dinov2",
         {{"embed_dim", d.embed_dim}, {"depth", d.depth}, {"num_heads", d.num_heads}, {"mlp_ratio", d.mlp_ratio},
          {"num_register_tokens", d.num_register_tokens}, {"qk_norm", d.qk_norm}, {"qk_norm_eps", d.qk_norm_eps},
          {"pos_grid", d.pos_grid}, {"interpolate_antialias", d.interpolate_antialias},
          {"interpolate_offset", d.interpolate_offset}, {"layerscale_init", d.layerscale_init},
          {"imagenet_normalize", d.imagenet_normalize}}}}},
      {"training",
       {{"lr", tr.lr}, {"beta1", tr.beta1}, {"beta2", tr.beta2}, {"eps", tr.eps}, {"weight_decay", tr.weight_decay},
        {"warmup", tr.warmup}, {"train_steps", tr.train_steps}, {"grad_clip_norm", tr.grad_clip_norm},
        {"allowed_gradnorm_factor", tr.allowed_gradnorm_factor}, {"batch_size", tr.batch_size},
        {"grad_accum_steps", tr.grad_accum_steps}, {"num_views", tr.num_views},
        {"num_input_views", tr.num_input_views}, {"num_target_views", tr.num_target_views},
        {"min_frame_dist", tr.min_frame_dist}, {"max_frame_dist", tr.max_frame_dist},
        {"l2_loss_weight", tr.l2_loss_weight}, {"perceptual_loss_weight", tr.perceptual_loss_weight},
        {"checkpoint_every", tr.checkpoint_every}, {"keep_checkpoints", tr.keep_checkpoints},
        {"log_every", tr.log_every}, {"eval_every", tr.eval_every}, {"seed", tr.seed},
        {"loader_threads", tr.loader_threads}, {"amp", tr.amp}}},
      {"dataset",
       {{"square_crop", ds.square_crop}, {"num_train_scenes", ds.num_train_scenes},
        {"num_test_scenes", ds.num_test_scenes}, {"frames_per_scene", ds.frames_per_scene},
        {"render_height", ds.render_height}, {"render_width", ds.render_width},
        {"frame_spacing", ds.frame_spacing}, {"eval_gap", ds.eval_gap}, {"seed", ds.seed}}},
      {"eval", {{"num_target_views", c.eval.num_target_views}, {"max_scenes", c.eval.max_scenes}}}};
}

}  // namespace uplvsm
