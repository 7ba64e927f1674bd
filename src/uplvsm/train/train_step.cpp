#include "uplvsm/train/train_step.h"

#include <cmath>

#include "uplvsm/core/autocast.h"
#include "uplvsm/train/gradient_difference_loss.h"
#include "uplvsm/train/optimizer.h"

namespace uplvsm::train {

namespace {

struct Losses {
  double loss = 0, mse = 0;
};

// Forward and losses under autocast, as the official step; the MSE on fp32 (autocast's policy for losses). The
// gradient difference term (not in the paper) outside autocast, on fp32 as well.
Losses forward_backward(StepContext& ctx, const MicroBatch& batch, double accum) {
  const auto& tc = ctx.training;
  const auto& target = batch.targets.images;
  torch::Tensor mse, loss, render;
  {
    AutocastGuard amp(target.device(), ctx.bf16);
    render = ctx.net->render(batch.inputs, batch.targets, ctx.target_poses).render;
    mse = torch::mse_loss(render.to(torch::kFloat32), target);
    loss = tc.l2_loss_weight * mse;
    if (ctx.perceptual) loss = loss + tc.perceptual_loss_weight * ctx.perceptual->forward(render, target);
  }
  if (tc.gradient_difference_weight > 0)
    loss = loss + tc.gradient_difference_weight * gradient_difference_loss(render, target);
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
    const auto losses = forward_backward(ctx, batch, accum);
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
