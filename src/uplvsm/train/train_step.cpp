#include "uplvsm/train/train_step.h"

#include <cmath>

#include "uplvsm/core/autocast.h"
#include "uplvsm/geometry/camera_rotation_warp.h"
#include "uplvsm/geometry/quaternion.h"
#include "uplvsm/model/latent_pose_refinement.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/estimator_half_view.h"
#include "uplvsm/train/gradient_difference_loss.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/rotation_alignment_loss.h"
#include "uplvsm/train/structural_dissimilarity_loss.h"
#include "uplvsm/train/turned_view_loss.h"

namespace uplvsm::train {

namespace {

struct Losses {
  double loss = 0, mse = 0;
};

// training.rotation_equivariance_weight's term: each target seen through a fixed central band, as it is and as its
// camera turned by a random yaw (drawn from the seed and the step, so a resumed run draws the same); the latent
// pose of the turned one must be the plain one's turned by that angle (rotation in Frobenius norm, the camera
// centre unchanged). The plain estimate is the reference (no gradient through it).
torch::Tensor rotation_equivariance_loss(model::UPLVSMImpl& net, const model::Views& targets,
                                         const torch::Tensor& scene_latents, const TrainingConfig& tc, int64_t step) {
  const auto& images = targets.images;
  const int64_t b = images.size(0), v = images.size(1), H = images.size(3), W = images.size(4);
  auto flat = images.flatten(0, 1);
  auto k = targets.fxfycxcy.flatten(0, 1);
  const double max_radians = tc.rotation_equivariance_degrees * M_PI / 180.0;
  auto generator =
      at::detail::createCPUGenerator(static_cast<uint64_t>(tc.seed) * 1000003u + static_cast<uint64_t>(step));
  auto angles = ((torch::rand({b * v}, generator, torch::kFloat32) * 2 - 1) * max_radians).to(images.device());
  auto turn = geometry::yaw_rotation(angles);
  auto band = geometry::yaw_safe_region(k, H, W, max_radians);
  auto plain = net.estimate_poses((flat * band).view_as(images), scene_latents).flatten(0, 1).to(torch::kFloat32);
  auto warped = geometry::warp_to_rotated_camera(flat, k, turn) * band;
  auto turned = net.estimate_poses(warped.view_as(images), scene_latents).flatten(0, 1).to(torch::kFloat32);
  using torch::indexing::Slice;
  auto expected = torch::matmul(geometry::quat_to_rotation(plain.index({Slice(), Slice(3, 7)})).detach(), turn);
  auto rotation_error =
      (geometry::quat_to_rotation(turned.index({Slice(), Slice(3, 7)})) - expected).pow(2).sum({1, 2});
  auto centre_error =
      (turned.index({Slice(), Slice(0, 3)}) - plain.index({Slice(), Slice(0, 3)}).detach()).pow(2).sum(1);
  return (rotation_error + centre_error).mean();
}

// training.latent_translation_warmup_steps for one step: the estimator's translation scaled by step / N, and 1
// again when the step is done (evaluation and checkpoints see the plain model).
class TranslationWarmup {
 public:
  TranslationWarmup(model::NovelViewModelImpl& net, const TrainingConfig& tc, int64_t step) {
    auto* up = model::as_uplvsm(net);
    if (tc.latent_translation_warmup_steps <= 0 || !up || step >= tc.latent_translation_warmup_steps) return;
    estimator_ = up->estimator.get();
    estimator_->translation_scale = static_cast<double>(step) / static_cast<double>(tc.latent_translation_warmup_steps);
  }
  ~TranslationWarmup() {
    if (estimator_) estimator_->translation_scale = 1.0;
  }
  TranslationWarmup(const TranslationWarmup&) = delete;
  TranslationWarmup& operator=(const TranslationWarmup&) = delete;

 private:
  model::LatentPluckerLearnerImpl* estimator_ = nullptr;
};

// The render, its MSE and (training.fitted_pose_steps) the estimator's pull towards the fitted poses.
struct ScoredRender {
  model::Rendered out;
  torch::Tensor mse;
  torch::Tensor pose_pull;  // undefined unless the poses are fitted
};

// training.fitted_pose_steps: each target's estimated latent pose is fitted to the target
// (model/latent_pose_refinement) and the render is scored there (training.render_at_fitted_poses), so the decoder
// learns what a well-placed camera shows rather than hedging against the estimator's misplacement, or at the
// estimator's poses as usual; either way the estimator is pulled to where the fit went. out.pose_enc stays the
// estimator's, for the other latent-pose terms.
ScoredRender render_with_fitted_poses(StepContext& ctx, const MicroBatch& batch) {
  auto& net = *model::as_uplvsm(*ctx.net);
  const auto& targets = batch.targets;
  auto latents = net.encode(batch.inputs);
  auto estimated = net.target_latent_poses(batch.inputs, targets, latents, model::TargetPoses::Estimator);
  const model::PoseRefinement fit{ctx.training.fitted_pose_steps, ctx.training.fitted_pose_lr, /*keep_best=*/true};
  auto fitted = model::refine_latent_poses(net, latents, estimated, targets, fit);
  const auto& scored_at = ctx.training.render_at_fitted_poses ? fitted : estimated;
  auto render = net.render_views(latents, scored_at, targets.fxfycxcy, targets.images.size(3), targets.images.size(4));
  auto mse = torch::mse_loss(render.to(torch::kFloat32), targets.images);
  auto pull = (estimated.to(torch::kFloat32) - fitted).pow(2).sum(-1).mean();
  return {model::Rendered{render, estimated, latents}, mse, pull};
}

// The render and its MSE: the official one, with training.fitted_pose_steps at fitted poses, or with
// model.estimator_half_view (and target poses from the estimator) the estimator shown one half of each target and the
// other half scored.
ScoredRender render_and_mse(StepContext& ctx, const MicroBatch& batch, int64_t step) {
  const auto& target = batch.targets.images;
  const bool estimated = ctx.target_poses == model::TargetPoses::Estimator;
  if (estimated && ctx.training.fitted_pose_steps > 0) return render_with_fitted_poses(ctx, batch);
  if (!ctx.net->config.estimator_half_view || !estimated) {
    auto out = ctx.net->render(batch.inputs, batch.targets, ctx.target_poses);
    auto mse = torch::mse_loss(out.render.to(torch::kFloat32), target);
    return {out, mse, {}};
  }
  auto& net = *model::as_uplvsm(*ctx.net);
  const int64_t b = target.size(0), v = target.size(1), H = target.size(3), W = target.size(4);
  auto seen = draw_seen_halves(b * v, H, W, ctx.training, step).to(target.device()).view({b, v, 1, H, W});
  auto latents = net.encode(batch.inputs);
  auto poses = net.estimate_poses_seeing(target, seen, latents);
  auto render = net.render_views(latents, poses, batch.targets.fxfycxcy, H, W);
  auto mse = masked_mse(render, target, 1 - seen);
  return {model::Rendered{render, poses, latents}, mse, {}};
}

// Forward and losses under autocast, as the official step; the MSE on fp32 (autocast's policy for losses).
Losses forward_backward(StepContext& ctx, const MicroBatch& batch, double accum, int64_t step) {
  const auto& tc = ctx.training;
  const auto& target = batch.targets.images;
  TranslationWarmup warmup(*ctx.net, tc, step);  // also through backward (checkpoint recomputation reads it)
  torch::Tensor mse, loss;
  model::Rendered out;
  {
    AutocastGuard amp(target.device(), ctx.bf16);
    auto scored = render_and_mse(ctx, batch, step);
    out = scored.out;
    mse = scored.mse;
    loss = tc.l2_loss_weight * mse;
    if (scored.pose_pull.defined()) loss = loss + tc.fitted_pose_weight * scored.pose_pull;
    if (ctx.perceptual) loss = loss + tc.perceptual_loss_weight * ctx.perceptual->forward(out.render, target);
    if (tc.l1_loss_weight > 0) loss = loss + tc.l1_loss_weight * (out.render.to(torch::kFloat32) - target).abs().mean();
    if (tc.latent_translation_weight > 0)
      loss =
          loss + tc.latent_translation_weight * out.pose_enc.narrow(-1, 0, 3).to(torch::kFloat32).pow(2).sum(-1).mean();
    if (tc.rotation_equivariance_weight > 0)
      loss = loss + tc.rotation_equivariance_weight * rotation_equivariance_loss(*model::as_uplvsm(*ctx.net),
                                                                                 batch.targets, out.scene_latents, tc,
                                                                                 step);
    if (tc.turned_view_weight > 0)
      loss = loss + tc.turned_view_weight *
                        turned_view_loss(*model::as_uplvsm(*ctx.net), batch.targets, out.pose_enc, out.scene_latents,
                                         draw_turn_angles(target.size(0) * target.size(1), tc, step));
    if (tc.rotation_alignment_weight > 0)
      loss = loss + tc.rotation_alignment_weight *
                        rotation_alignment_loss(batch.inputs, batch.targets, out.pose_enc, tc.rotation_alignment_blur);
  }
  // Outside autocast: SSIM's local variances are differences of near-equal means, which bf16 would cancel.
  if (tc.ssim_loss_weight > 0) loss = loss + tc.ssim_loss_weight * structural_dissimilarity_loss(out.render, target);
  if (tc.gradient_difference_weight > 0)
    loss = loss + tc.gradient_difference_weight * gradient_difference_loss(out.render, target);
  (loss / accum).backward();
  return {loss.item<double>() / accum, mse.item<double>() / accum};
}

// Data parallel: every rank takes the same decisions from averaged gradients and losses, and stops when any rank
// got a signal.
void agree_across_ranks(Communicator& comm, const std::vector<torch::Tensor>& params, StepResult& r) {
  average_gradients(comm, params);
  auto shared = torch::tensor({r.loss, r.mse, r.stop ? 1.0 : 0.0}, torch::kFloat64);
  comm.allreduce_sum({shared});
  r.loss = shared[0].item<double>() / comm.world_size();
  r.mse = shared[1].item<double>() / comm.world_size();
  r.stop = shared[2].item<double>() > 0;
}

// The trainer's optimiser is AdamW (make_optimizer): its one-pass step; any other optimiser takes its own.
void step_optimizer(torch::optim::Optimizer& optimizer) {
  if (auto* adamw = dynamic_cast<torch::optim::AdamW*>(&optimizer))
    adamw_step(*adamw);
  else
    optimizer.step();
}

// The official skip rules around AdamW (see the header).
void apply_update(StepContext& ctx, TrainState& state, StepResult& r) {
  const auto& tc = ctx.training;
  if (!std::isfinite(r.loss)) {
    ++state.skipped_nonfinite;  // official: no optimiser step, no scheduler step
    r.skipped = true;
    return;
  }
  for (auto& p : ctx.params)
    if (p.grad().defined()) p.grad().nan_to_num_(0.0, 1e-6, -1e-6);
  // Official: grad_clip_norm 0 turns off clipping and the skip rule alike, and the logged norm is 0 (not measured).
  if (tc.grad_clip_norm > 0) r.grad_norm = torch::nn::utils::clip_grad_norm_(ctx.params, tc.grad_clip_norm);
  if (tc.grad_clip_norm > 0 && r.grad_norm > tc.grad_clip_norm * tc.allowed_gradnorm_factor) {
    ++state.skipped_gradnorm;  // official: skip the update, still advance the schedule
    r.skipped = true;
  } else {
    set_learning_rate(*ctx.optimizer, r.lr);
    step_optimizer(*ctx.optimizer);
    ++state.param_update_step;
  }
  ++state.scheduler_step;
}

}  // namespace

void release_gradients(const std::vector<torch::Tensor>& params) {
  for (const auto& p : params) p.mutable_grad().reset();
}

std::vector<torch::Tensor> trainable_parameters(const torch::nn::Module& module) {
  std::vector<torch::Tensor> params;
  for (const auto& p : module.parameters())
    if (p.requires_grad()) params.push_back(p);
  return params;
}

StepResult train_step(StepContext& ctx, TrainState& state, const std::vector<MicroBatch>& micro_batches,
                      bool stop_requested) {
  TORCH_CHECK(!micro_batches.empty(), "train_step: no micro-batches");
  const auto& tc = ctx.training;
  StepResult r;
  r.stop = stop_requested;
  release_gradients(ctx.params);
  const auto accum = static_cast<double>(micro_batches.size());
  for (const auto& batch : micro_batches) {
    const auto losses = forward_backward(ctx, batch, accum, state.step);
    r.loss += losses.loss;
    r.mse += losses.mse;
  }
  if (ctx.comm) agree_across_ranks(*ctx.comm, ctx.params, r);
  r.lr = tc.lr * lr_lambda(state.scheduler_step, tc.warmup, tc.train_steps);
  apply_update(ctx, state, r);
  ++state.step;
  return r;
}

}  // namespace uplvsm::train
