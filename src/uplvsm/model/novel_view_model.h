// The model family's one interface. Every model renders a scene's target views from its input views; where the
// targets' cameras come from is one seam, TargetPoses. Train, eval, render and study hold a NovelViewModel and never
// ask which model it is; model_factory.h builds the right one from a config or a checkpoint:
//
//   NovelViewModel       DINOv2 image tokens, Plücker ray tokens, RGB head; render(inputs, targets, TargetPoses)
//     ├── UPLVSM         unposed inputs -> scene latents; targets posed by the estimator, the mapper or the dataset
//     └── PosedLVSM      decoder-only over posed inputs: PT-LVSM (input view 0 posed), LVSM (every input view posed)
//
// What only UP-LVSM has (scene latents, the Latent Plücker Learner, the pose mapper) lives on its type (uplvsm.h).
#pragma once
#include <torch/torch.h>

#include <functional>
#include <initializer_list>
#include <string>
#include <utility>

#include "uplvsm/core/config.h"
#include "uplvsm/data/scene.h"
#include "uplvsm/model/dinov2.h"
#include "uplvsm/model/pose_tokenizer.h"
#include "uplvsm/model/rgb_head.h"

namespace uplvsm::model {

// Intermediates of one forward, filled when a trace is passed (parity tests, analysis tools).
struct ForwardTrace {
  torch::Tensor input_dino_tokens;   // [b, v_in, n, d] (the posed models: with their cameras' ray tokens added)
  torch::Tensor canonical_plucker;   // [b, v, 6, H, W] UP-LVSM: identity camera per input; posed: the marked views'
  torch::Tensor encoder_input;       // [b, L + v_in n, d] latents ; marked input tokens (analysis replays blocks)
  torch::Tensor encoder_output;      // [b, L + v_in n, d]
  torch::Tensor target_dino_tokens;  // [b, v_t, n, d]
  torch::Tensor estimator_pooled;    // [b, v_t, d]
  torch::Tensor target_plucker;      // [b, v_t, 6, H, W]
};

// Keeps intermediates when a trace is wanted: keep(trace, {{&ForwardTrace::encoder_output, z}, ...}); no-op for null.
void keep(ForwardTrace* trace, std::initializer_list<std::pair<torch::Tensor ForwardTrace::*, torch::Tensor>> fields);

// The frame a batch's c2w are in: the dataset's world frame, or already the official scene frame (the training
// loader's, over all the sample's views, before its pose noise), which the posed models take as it is instead of
// normalising over these inputs and targets.
enum class CameraFrame { World, Scene };

// A batch of view sets (data::SceneViews is one scene's, unbatched). c2w is needed only where a camera comes from
// the dataset; unposed photos leave it undefined.
struct Views {
  torch::Tensor images;    // [b, v, 3, H, W] in [0, 1]
  torch::Tensor fxfycxcy;  // [b, v, 4] pixels
  torch::Tensor c2w;       // [b, v, 4, 4] or undefined
  CameraFrame camera_frame = CameraFrame::World;
};
// One scene's views as a batch of one on `device` (c2w stays undefined where the scene has none).
Views batch_of_one(const data::SceneViews& views, torch::Device device);

// Where the target views' cameras come from: one enum from the config to the render (core/config.h).
using uplvsm::TargetPoses;

struct Rendered {
  torch::Tensor render;         // [b, v_t, 3, H, W] in [0, 1]
  torch::Tensor pose_enc;       // [b, v_t, 7] the latent poses rendered (t, q_xyzw); undefined for the posed models
  torch::Tensor scene_latents;  // UP-LVSM: what the targets were rendered from (undefined for the posed models)
};

// Renders one scene at real cameras: poses [b, n, 7] in camera-control units (model/pose_mapper.h), intrinsics
// [b, n, 4] pixels, an H x W target -> [b, n, 3, H, W]. Valid while its model lives.
using CameraRenderer = std::function<torch::Tensor(const torch::Tensor& poses, const torch::Tensor& fxfycxcy,
                                                   int64_t height, int64_t width)>;

class NovelViewModelImpl : public torch::nn::Module {
 public:
  // The targets [b, v_t, 3, H, W] rendered from the inputs, the targets' cameras from `source`. The targets' images
  // give the output size (and are what the estimator reads); their c2w is needed by Mapper and Dataset.
  virtual Rendered render(const Views& inputs, const Views& targets, TargetPoses source,
                          ForwardTrace* trace = nullptr) = 0;
  // The target poses of the model's own protocol ("auto"): the estimator for UP-LVSM, dataset cameras otherwise.
  virtual TargetPoses default_target_poses() const = 0;
  // Whether camera_control can place real cameras: UP-LVSM through its pose mapper, the posed models always.
  virtual bool has_camera_control() const = 0;
  // Prepares a scene (batch of inputs) once for rendering real cameras in chunks: UP-LVSM encodes its latents, the
  // posed models keep the inputs, whose c2w they need. Throws when the model has no camera control.
  virtual CameraRenderer camera_control(const Views& inputs) = 0;
  // The paper's name of the model ("UP-LVSM", "PT-LVSM", "LVSM"), for messages.
  virtual std::string name() const = 0;
  // Gradient checkpointing of the transformer stacks in groups of k blocks (0: off).
  virtual void set_grad_checkpoint_every(int64_t k);

  // images [b, v, 3, H, W] in [0, 1] -> DINOv2 tokens [b, v, n, d]
  torch::Tensor tokenize(const torch::Tensor& images);
  int64_t parameter_count() const;

  ModelConfig config;
  DinoTokenizer tokenizer{nullptr};  // registered as image_tokenizer.1 (official key prefix)
  PoseTokenizer target_pose_tokenizer{nullptr}, canonical_pose_tokenizer{nullptr};
  RgbHead image_token_decoder{nullptr};
  int64_t grad_checkpoint_every = 0;

 protected:
  explicit NovelViewModelImpl(const ModelConfig& config) : config(config) {}
  // The shared parts, registered by each model where its official module has them: the registration order fixes
  // the parameter order and, for a seed, the initial weights. register_rgb_head also gives the ray tokenizers and
  // the head their N(0, 0.02) initialisation, after every other part (that order too decides the initial weights).
  void register_tokenizers();
  void register_rgb_head();
  // tokens [b, v, n, d] with canonical_pose_tokenizer(rays [b, k, 6, H, W]) added to its first k views.
  torch::Tensor with_camera_tokens(const torch::Tensor& tokens, const torch::Tensor& rays);
  // [b, L, d] -> [b v, L, d], each sample repeated for its v views ('(b v)': batch major, view minor).
  static torch::Tensor repeat_per_view(const torch::Tensor& x, int64_t views);
};
TORCH_MODULE(NovelViewModel);

// The c2w of `which` ("input", "target") views, checked against their images; the error says `source` needs them.
const torch::Tensor& require_c2w(const Views& views, const char* which, TargetPoses source);

// The source this model renders from: Auto is the model's own (default_target_poses), any other as it is.
TargetPoses resolve_target_poses(TargetPoses choice, const NovelViewModelImpl& model);

}  // namespace uplvsm::model
