// One optimiser step of the official training loop (Less3Depend `src/train.py`), as a function of its own so the
// loop in trainer.cpp reads as named steps and tests can replay the official steps through this very code:
//   per micro-batch: forward (autocast) -> loss = w_l2 MSE (+ w_p perceptual; + w_gd gradient difference, not in the
//   paper) -> backward(loss / accum)
//   [data parallel: average gradients and losses]
//   non-finite loss: no update, schedule does not move; else nan_to_num(grads) -> clip (norm returned BEFORE
//   clipping) -> skip the update when norm > clip x factor -> AdamW at the scheduled LR; the schedule moves.
//   grad_clip_norm 0: neither the clip nor the skip rule (the norm is reported as 0), as the official.
#pragma once
#include <torch/torch.h>

#include <vector>

#include "uplvsm/core/config.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/distributed.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::train {

// The views of one micro-batch, already on the training device.
struct MicroBatch {
  model::Views inputs;
  model::Views targets;
};

// What a step needs besides its batches; built once per run.
struct StepContext {
  model::NovelViewModelImpl* net = nullptr;
  torch::optim::Optimizer* optimizer = nullptr;
  std::vector<torch::Tensor> params;  // trainable parameters (clipped together, as the official loop)
  TrainingConfig training;
  model::TargetPoses target_poses = model::TargetPoses::Estimator;
  PerceptualLoss perceptual{nullptr};  // null: MSE only
  bool bf16 = false;
  Communicator* comm = nullptr;  // null: one process
};

struct StepResult {
  double loss = 0, mse = 0;  // averaged over micro-batches (and ranks)
  double lr = 0;             // the learning rate this step used (scheduled; also when the update was skipped)
  double grad_norm = 0;      // total norm before clipping (0 on a non-finite loss or with clipping off)
  bool skipped = false;      // no parameter update (non-finite loss, or gradient norm above clip x factor)
  bool stop = false;         // some rank asked to stop (a signal); agreed by every rank
};

// Drops the parameters' gradients, not zeroing them in place as LibTorch 1.13's zero_grad does: PyTorch 2's
// zero_grad(set_to_none=True), which the official trainer calls. The x224 model's 1 GiB of gradients then exists only
// from its backward to its update, not beside the next forward's saved activations; a parameter that receives no
// gradient is skipped by AdamW (no decay, no moment update), as there.
void release_gradients(const std::vector<torch::Tensor>& params);

// The trainable parameters of a module, in registration order.
std::vector<torch::Tensor> trainable_parameters(const torch::nn::Module& module);

// Runs one step over `micro_batches` (grad_accum_steps of them) and advances `state` (step, scheduler, skip counts).
StepResult train_step(StepContext& ctx, TrainState& state, const std::vector<MicroBatch>& micro_batches,
                      bool stop_requested = false);

}  // namespace uplvsm::train
