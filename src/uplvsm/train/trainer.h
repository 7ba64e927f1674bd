// The training loop (official recipe): batches from the step-keyed loader, the model's forward with the run's target
// poses (UP-LVSM: the estimator on the target images), MSE (+ perceptual when available) loss, AdamW with
// warmup+cosine, gradient clipping with the official skip rules, JSONL metrics, atomic checkpoints with rotation,
// exact resume (train/run_start.h) and SIGINT/SIGTERM checkpointing.
#pragma once
#include <torch/torch.h>

#include <functional>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "uplvsm/core/config.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/train/distributed.h"
#include "uplvsm/train/perceptual_loss.h"
#include "uplvsm/train/train_step.h"

namespace uplvsm::train {

struct TrainOptions {
  std::string data_root;        // pixelSplat-format root with a train/ split
  std::string run_dir;          // config.json, metrics.jsonl, checkpoints/
  std::string resume = "auto";  // "auto" (newest readable checkpoint in run_dir, if any), "none", or a path
  // Weights for a new run (ignored when resuming): UP-LVSM loaded strictly, or DINOv2 into the image tokenizer.
  std::string init_weights;
  // VGG19 weights (torchvision `features.N.*`) for the perceptual loss; without them a config asking for the
  // perceptual loss trains with MSE only, with a warning.
  std::string perceptual_weights;
  VggInput perceptual_input = VggInput::Auto;  // the input those weights expect (Auto: the file's marker)
  torch::Device device = torch::kCPU;
  int64_t stop_after_steps = -1;  // stop (with a checkpoint) after this many steps of this invocation
  bool progress = true;
  // Data-parallel group (train/distributed.h); null: one process. Rank 0 writes the logs and checkpoints.
  std::shared_ptr<Communicator> comm;
  // Periodic evaluation, every training.eval_every steps and at the end, on rank 0 with the model in eval mode
  // (other ranks wait). Its result is logged to metrics.jsonl as {"step", "eval": result}. eval::periodic_evaluation
  // makes it (eval/ sits beside train/, not below it); train and the grid studies pass it.
  std::function<nlohmann::json(model::NovelViewModel& net, int64_t step)> periodic_eval;
};

struct TrainResult {
  int64_t step = 0;  // steps completed in total
  double last_loss = 0, last_psnr = 0;
  double seconds = 0;  // this invocation
  std::string last_checkpoint;
  bool interrupted = false;  // stopped by a signal
};

TrainResult train(const Config& config, const TrainOptions& options);

// The loader settings a run of `config` reads its batches with (this rank's shard when `comm` is given).
data::LoaderOptions loader_options(const Config& config, const data::ChunkDataset& dataset, const Communicator* comm);

// Everything a step needs besides its batches: the loss terms, bf16 autocast and TF32 as the config asks (TF32 is
// set on the process for a CUDA device), gradient checkpointing; built once per run.
StepContext step_context(model::NovelViewModelImpl& net, torch::optim::Optimizer& optimizer, const Config& config,
                         const TrainOptions& opt);

// A loader batch as the model reads it, on `device`: the told cameras, in the scene frame of the sample's views.
MicroBatch micro_batch(const data::TrainingBatch& batch, int64_t input_views, torch::Device device);

}  // namespace uplvsm::train
