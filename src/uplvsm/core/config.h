// The run configuration: model, training and built-in dataset settings, read from configs/*.json. Field names
// follow the official UP-LVSM YAML where one exists (transformer.encoder_n_layer, training.min_frame_dist, ...).
// Unknown keys are errors, so a typo never silently falls back to a default; keys of levers removed since
// (core/retired_keys.h) are accepted at their old default, so files written before still load.
#pragma once
#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm {

// The string-valued choices, parsed once when a config is read (JSON keeps their names).
enum class Variant { UPLVSM, PTLVSM, LVSM };  // model.variant: "uplvsm", "ptlvsm", "lvsm"
enum class Amp { None, Bf16 };                // training.amp: "none", "bf16"
// Where a target view's camera comes from (training.target_poses, --target-poses, a model's render): the model's
// own (auto: the estimator for uplvsm, dataset cameras for the posed variants); the Latent Plücker Learner reading the
// target image (the paper's protocol); dataset cameras through the pose mapper (camera control); dataset cameras
// directly (the posed variants, and for UP-LVSM the "SfM target poses" ablation).
enum class TargetPoses { Auto, Estimator, Mapper, Dataset };  // "auto", "estimator", "mapper", "dataset"

std::string to_string(Variant v);
std::string to_string(Amp a);
std::string to_string(TargetPoses t);
// Each throws naming `field`, the accepted names and the value given.
Variant parse_variant(const std::string& name, const std::string& field = "model.variant");
Amp parse_amp(const std::string& name, const std::string& field = "amp");
TargetPoses parse_target_poses(const std::string& name, const std::string& field = "target poses");

struct TransformerConfig {
  int64_t d = 768;
  int64_t d_head = 64;
  int64_t encoder_n_layer = 6;
  int64_t estimator_n_layer = 4;
  int64_t decoder_n_layer = 14;
  int64_t n_layer = 24;  // the decoder-only posed variants (ptlvsm, lvsm): official `transformer.n_layer`
  int64_t n_latent_vectors = 1024;
  double qk_norm_eps = 1e-3;  // official UP-LVSM; LVSM uses 1e-5
  bool special_init = true;
  bool depth_init = true;
  // Not in the paper: a latent camera that only turns. The estimator's translation is zero in training and
  // inference (its head stays in the checkpoint, unused), so every camera change must be explained by a rotation.
  bool rotation_only_latent_camera = false;
};

struct Dinov2Config {
  int64_t embed_dim = 768;  // must equal transformer.d: tokens are used directly
  int64_t depth = 12;
  int64_t num_heads = 12;
  int64_t mlp_ratio = 4;
  int64_t num_register_tokens = 4;
  bool qk_norm = true;  // official UP-LVSM adds RMSNorm QK-norm (eps 1e-3) inside DINOv2 attention
  double qk_norm_eps = 1e-3;
  int64_t pos_grid = 37;  // pos_embed covers pos_grid^2 patches (518 px for patch 14)
  bool interpolate_antialias = true;
  double interpolate_offset = 0.0;
  double layerscale_init = 1.0;
  bool imagenet_normalize = false;  // official UP-LVSM feeds [0,1] images without mean/std
  // Initial pos_embed of a tokenizer trained from scratch: "normal" (timm's N(0, 0.02); pretrained weights replace
  // it) or "sincos" (fixed-scale 2-D sine-cosine as MAE: patches tell their position apart from the first step).
  std::string pos_embed_init = "normal";
};

struct ModelConfig {
  Variant variant = Variant::UPLVSM;  // ptlvsm: posed targets; lvsm: posed inputs and targets
  bool pose_mapper = false;           // camera control: the linear pose mapper (model/pose_mapper.h), uplvsm only
  // uplvsm: the encoder's outputs at the input image tokens join the scene latents as the scene representation the
  // estimator and the decoder attend to (official: discarded, only the latents are kept). A lever against the latent
  // bottleneck at small scale (docs/demo.md); the weights are the same, so any checkpoint loads either way.
  bool keep_image_tokens = false;
  // Not in the paper (RayZer's design, Jiang et al. 2025: the inputs' predicted cameras feed the scene
  // reconstruction): uplvsm's encoder runs twice, the second time with input views 1.. carrying the Plücker rays of
  // the latent poses the estimator reads from them in the first pass's scene (view 0 the identity marker), so one
  // latent camera must serve both the encoder's fusion of the inputs and the decoder's render. false: official.
  bool encoder_latent_cameras = false;
  int64_t image_size = 224;
  int64_t patch_size = 14;
  TransformerConfig transformer;
  Dinov2Config dinov2;
};

struct TrainingConfig {
  double lr = 4e-4;
  double beta1 = 0.9, beta2 = 0.95, eps = 1e-8;
  double weight_decay = 0.05;
  int64_t warmup = 4000;
  int64_t train_steps = 100000;
  double grad_clip_norm = 1.0;
  double allowed_gradnorm_factor = 4.0;
  int64_t batch_size = 16;  // scenes per micro-batch on one process (the official batch_size_per_gpu)
  int64_t grad_accum_steps = 1;
  // Scenes per optimiser step over all processes and accumulated micro-batches (the official batch_size_per_gpu x
  // GPUs x grad_accum_steps: 128 at x224, 48 at x518). > 0: the accumulation is derived from it and the run's number
  // of processes (train/global_batch.h); 0: batch_size x grad_accum_steps on each process, as given.
  int64_t global_batch_size = 0;
  int64_t grad_checkpoint_every = 0;  // checkpoint transformer blocks in groups of this many (official: 1); 0 off
  int64_t num_views = 8;
  int64_t num_input_views = 2;
  int64_t num_target_views = 6;
  int64_t min_frame_dist = 25;
  int64_t max_frame_dist = 192;
  // A baseline curriculum (not in the paper): the largest context gap grows from min_frame_dist to max_frame_dist
  // over the first frame_dist_curriculum_steps steps (ordered views only); 0: max_frame_dist from the start.
  int64_t frame_dist_curriculum_steps = 0;
  double l2_loss_weight = 1.0;
  double perceptual_loss_weight = 0.0;  // 0.5 in the paper; needs VGG19 weights (TrainOptions::perceptual_weights)
  // Not in the paper: the gradient difference loss (train/gradient_difference_loss.h), against the blur. 0: off.
  double gradient_difference_weight = 0.0;
  // Ours, an explicit opt-out: true lets a new run of a full-size DINOv2 tokenizer (ViT-B/14, the size of Meta's
  // released weights) start from random weights. false: such a run needs --init (the official code always loads
  // dinov2_vitb14_reg4_pretrain.pth); smaller tokenizers (tiny, demo) have no released weights and start random.
  bool random_tokenizer = false;
  int64_t checkpoint_every = 4000;
  int64_t keep_checkpoints = 3;
  int64_t log_every = 10;
  int64_t eval_every = 0;  // 0: no periodic evaluation
  int64_t seed = 777;
  int64_t loader_threads = 2;
  Amp amp = Amp::None;
  // TF32 tensor-core matmuls and convolutions for the run's fp32 work on CUDA (the official `use_tf32`: true in the
  // paper's recipe); no effect on CPU.
  bool tf32 = false;
  // Where targets' cameras come from (model::TargetPoses): "auto" (estimator for uplvsm, dataset for the posed
  // variants), "estimator", "mapper" (camera-control fine-tuning) or "dataset" (the SfM-target-pose ablation).
  TargetPoses target_poses = TargetPoses::Auto;
  // Nested training subsets (the scalability study): train on the first N scenes of the train split; 0: all.
  int64_t max_train_scenes = 0;
  // Ours: an epoch visits the chunks this many at a time, shuffling their scenes together, so the chunk cache
  // serves consecutive samples; 0: one shuffle over the whole split (the official order; a chunk read per sample).
  int64_t chunks_per_shuffle = 2;
  // A subset manifest (`uplvsm dataset subset`: little / medium / large / full or custom): train on its scenes only.
  // max_train_scenes then counts within it. Empty: the whole train split.
  std::string subset;
  // The pose-noise study, the official `unposed.noise_scale`: N(0, pose_noise_std^2) (a standard deviation) added to
  // the 7-D (t, q) encoding of the input and, drawn apart, the target cameras, in the scene frame of the sample's
  // views (data/loader.h). 0: clean cameras. Only variants that read training cameras are affected.
  double pose_noise_std = 0;
  // How training views are drawn from a scene: "ordered" (the official selector: two context frames min..max
  // frame_dist apart, targets between them; video datasets), "unordered" (any distinct frames; object renders
  // whose frames have no order), or "auto" (the dataset's dataset.json view_order; ordered without one).
  std::string view_sampler = "auto";
};

struct DatasetConfig {
  bool square_crop = true;
  // Built-in data (uplvsm make-dataset): "rooms" (walkthroughs, ordered frames) or "objects" (one object seen
  // from frames_per_scene random cameras on a sphere, unordered).
  std::string kind = "rooms";
  int64_t num_train_scenes = 400;
  int64_t num_test_scenes = 64;
  int64_t frames_per_scene = 32;
  int64_t render_height = 72;
  int64_t render_width = 128;
  double frame_spacing = 1.0;
  // Scales the size of every surface pattern (checkers, stripes, dots, floor planks); 1 = the original scenes.
  double texture_scale = 1.0;
  int64_t eval_gap = 0;  // frames between the two evaluation context views; 0: frames / 2
  int64_t seed = 1;
};

struct EvalConfig {
  int64_t max_scenes = 0;  // 0: all
};

struct Config {
  std::string name = "unnamed";
  ModelConfig model;
  TrainingConfig training;
  DatasetConfig dataset;
  EvalConfig eval;
};

// Reads a config file. A file may name another with "extends" (relative to its own folder): the base's keys, then
// this file's written over them (sections merged key by key), so a variant holds only what differs; chains resolve
// to 8 files, a cycle is an error, and "name" is never inherited (absent: the file's stem).
Config load_config(const std::string& path);
// Command-line overrides "section.field=value" (e.g. training.lr=3e-4, model.transformer.n_latent_vectors=64),
// applied in order, then validated like a file. Throws naming the assignment for an unknown field.
Config apply_config_overrides(const Config& c, const std::vector<std::string>& assignments, const std::string& source);
Config config_from_json(const nlohmann::json& j, const std::string& source = "<json>");
nlohmann::json config_to_json(const Config& c);
// Throws with a clear message when the combination is inconsistent (sizes not divisible, d != dino width, ...).
void validate_config(const Config& c, const std::string& source);

}  // namespace uplvsm
