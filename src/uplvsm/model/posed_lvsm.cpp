#include "uplvsm/model/posed_lvsm.h"

#include <tuple>

#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/geometry/plucker.h"
#include "uplvsm/model/pose_mapper.h"

namespace uplvsm::model {

PosedLVSMImpl::PosedLVSMImpl(const ModelConfig& c, PosedInputs posed) : NovelViewModelImpl(c), posed_inputs(posed) {
  const auto& t = c.transformer;
  register_tokenizers();
  // ptlvsm.py `_init_transformer`: the official per-block rule over the stack's n_layer blocks.
  transformer_blocks = register_module(
      "transformer_blocks", make_transformer_stack(t.d, t.d_head, t.qk_norm_eps,
                                                   official_block_init_stds(t.n_layer, t.special_init, t.depth_init)));
  transformer_input_layernorm = register_module("transformer_input_layernorm", LayerNorm(t.d, 1e-5, false));
  register_rgb_head();
}

namespace {

// The official cameras: per sample, inputs and targets normalised together (training, evaluation), or by the inputs
// alone (a camera path, whose frames must not move the frame).
std::pair<torch::Tensor, torch::Tensor> scene_normalized(const torch::Tensor& in_c2w, const torch::Tensor& tg_c2w,
                                                         bool with_targets) {
  TORCH_CHECK(torch::isfinite(in_c2w).all().item<bool>() && torch::isfinite(tg_c2w).all().item<bool>(),
              "posed model: camera matrices contain NaN or Inf");
  const int64_t vi = in_c2w.size(1);
  std::vector<torch::Tensor> per_sample;
  auto all = torch::cat({in_c2w, tg_c2w}, 1);
  for (int64_t i = 0; i < all.size(0); ++i)
    per_sample.push_back(geometry::official_scene_normalize(all[i], with_targets ? all[i] : in_c2w[i]));
  auto normalised = torch::stack(per_sample).to(in_c2w.scalar_type());
  return {normalised.narrow(1, 0, vi), normalised.narrow(1, vi, tg_c2w.size(1))};
}

}  // namespace

torch::Tensor PosedLVSMImpl::render_posed(const Views& inputs, const Views& targets, ForwardTrace* trace,
                                          bool normalize_with_targets) {
  const auto& images = inputs.images;
  TORCH_CHECK(images.dim() == 5 && images.size(2) == 3, "render_posed: input images must be [b, v, 3, H, W], got ",
              images.sizes());
  const int64_t b = images.size(0), vi = images.size(1), H = targets.images.size(3), W = targets.images.size(4);
  const int64_t vt = targets.fxfycxcy.size(1);
  auto in_c2w = require_c2w(inputs, "input", TargetPoses::Dataset);
  auto tg_c2w = require_c2w(targets, "target", TargetPoses::Dataset);
  if (!(inputs.camera_frame == CameraFrame::Scene && targets.camera_frame == CameraFrame::Scene))
    std::tie(in_c2w, tg_c2w) = scene_normalized(in_c2w, tg_c2w, normalize_with_targets);
  auto tokens = tokenize(images);  // [b, vi, n, d]
  const int64_t n = tokens.size(2), d = tokens.size(3);
  const int64_t posed = posed_inputs == PosedInputs::All ? vi : 1;
  auto in_rays = geometry::plucker_rays(in_c2w.narrow(1, 0, posed), inputs.fxfycxcy.narrow(1, 0, posed), images.size(3),
                                        images.size(4));
  tokens = with_camera_tokens(tokens, in_rays);
  auto context = repeat_per_view(tokens.reshape({b, vi * n, d}), vt);  // [b vt, vi n, d]
  auto tg_rays = geometry::plucker_rays(tg_c2w, targets.fxfycxcy, H, W);
  auto q = target_pose_tokenizer(tg_rays.flatten(0, 1));
  auto x = transformer_input_layernorm(torch::cat({context, q}, 1));
  auto y = run_stack(transformer_blocks, x, grad_checkpoint_every, "uplvsm::decoder", OutputRows{vi * n, q.size(1)});
  keep(trace, {{&ForwardTrace::input_dino_tokens, tokens},
               {&ForwardTrace::canonical_plucker, in_rays},
               {&ForwardTrace::target_plucker, tg_rays}});
  return image_token_decoder(y, b, vt, H, W);
}

Rendered PosedLVSMImpl::render(const Views& inputs, const Views& targets, TargetPoses source, ForwardTrace* trace) {
  TORCH_CHECK(resolve_target_poses(source, *this) == TargetPoses::Dataset, name(),
              " renders from dataset cameras only; target poses '", uplvsm::to_string(source), "' do not apply");
  return {render_posed(inputs, targets, trace), {}, {}};
}

CameraRenderer PosedLVSMImpl::camera_control(const Views& inputs) {
  TORCH_CHECK(inputs.c2w.defined(), name(), " renders from cameras: it needs the input views' c2w (dataset scenes)");
  return [this, inputs](const torch::Tensor& poses, const torch::Tensor& fxfycxcy, int64_t H, int64_t W) {
    const int64_t b = poses.size(0), n = poses.size(1);
    Views targets{torch::zeros({1, 1, 1, 1, 1}, fxfycxcy.options()).expand({b, n, 3, H, W}), fxfycxcy,
                  geometry::camera_control_to_world(inputs.c2w, poses)};
    return render_posed(inputs, targets, nullptr, /*normalize_with_targets=*/false);
  };
}

PosedInputs posed_inputs(Variant variant) {
  TORCH_CHECK(variant != Variant::UPLVSM, "the uplvsm variant has no posed inputs");
  return variant == Variant::PTLVSM ? PosedInputs::First : PosedInputs::All;
}

}  // namespace uplvsm::model
