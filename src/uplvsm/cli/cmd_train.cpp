// `uplvsm train`: trains UP-LVSM from images alone on a pixelSplat-format dataset; resumable.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/eval/training_evaluation.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/train/tokenizer_pretraining.h"
#include "uplvsm/train/train_request.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::cli {

namespace {

struct TrainArgs {
  CommonOptions common;
  train::TrainRequest r;
  int64_t stop_after = -1, ranks = 0;
  bool dry_run = false;
  train::VggInput vgg19_input = train::VggInput::Auto;
};

void add_train_options(CLI::App* cmd, TrainArgs& a) {
  add_common_options(cmd, a.common);
  cmd->add_option("--config", a.r.config_path, "config JSON (configs/tiny.json, configs/paper_x224.json)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--data", a.r.data, "dataset root (pixelSplat chunks with a train/ split); optional with --dry-run")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--run", a.r.run,
                  "run directory (config snapshot, metrics.jsonl, checkpoints/); optional with --dry-run");
  cmd->add_flag("--dry-run", a.dry_run,
                "print what the run will do (global batch, schedule, precision, loss terms, data and shuffling) and "
                "the checks made before training, then exit: no weights loaded; with --data, its train split's size");
  cmd->add_option("--ranks", a.ranks,
                  "with --dry-run: plan for this many data-parallel processes (default: torchrun's WORLD_SIZE, else 1)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--resume", a.r.resume,
                  "auto (the newest checkpoint in --run that reads, if any: a damaged newer one is skipped with a "
                  "warning), none, or a checkpoint path (an error if it does not read)")
      ->capture_default_str();
  cmd->add_option("--init", a.r.init,
                  "start a new run from these weights: UP-LVSM (ours or official, loaded strictly) or DINOv2 "
                  "(Meta .pth or HuggingFace safetensors, into the image tokenizer, as the official code does); a "
                  "run or checkpoints directory means its latest checkpoint")
      ->check(CLI::ExistingPath);
  cmd->add_option("--vgg19", a.r.vgg19,
                  "VGG19 weights for the perceptual loss (torchvision features.N.*: torchvision vgg19 .pth, or the "
                  "<out>.vgg19.safetensors that `uplvsm convert` extracts from an official checkpoint); a config "
                  "with training.perceptual_loss_weight > 0 refuses to start without it")
      ->check(CLI::ExistingFile);
  add_vgg19_input_option(cmd, a.vgg19_input);
  cmd->add_option("--amp", a.r.amp, "override training.amp: none (fp32) or bf16 (autocast, fp32 master weights)")
      ->check(CLI::IsMember({"none", "bf16"}));
  cmd->add_option("--stage", a.r.stage,
                  "main: the config as given; mapper: camera-control fine-tuning (paper appendix) - adds the linear "
                  "pose mapper (model.pose_mapper), fitted by least squares to the --init model's estimator, and "
                  "trains the whole model with target poses from dataset cameras through the mapper "
                  "(training.target_poses = mapper); use a mapper config for the paper's lr 1e-4 / 8K steps "
                  "(configs/*_mapper.json); tokenizer: self-supervised pretraining of the image tokenizer alone by "
                  "masked image modelling on the train split's images (no cameras), written to "
                  "<run>/tokenizer.safetensors in DINOv2 format for a later run's --init")
      ->check(CLI::IsMember({"main", "mapper", "tokenizer"}))
      ->capture_default_str();
  cmd->add_option("--set", a.r.set,
                  "override a config field, section.field=value (repeatable), e.g. --set training.warmup=500 --set "
                  "model.transformer.n_latent_vectors=64; the run's config.json records the result");
  cmd->add_option("--steps", a.r.steps, "override training.train_steps");
  cmd->add_option("--stop-after", a.stop_after, "stop after this many steps of this invocation (checkpointed)");
  cmd->add_option("--subset", a.r.subset,
                  "override training.subset: a manifest from `uplvsm dataset subset` (little/medium/large/full)")
      ->check(CLI::ExistingFile);
}

train::TrainOptions train_options(const TrainArgs& a, const Config& config) {
  train::TrainOptions opt;
  opt.data_root = a.r.data;
  opt.run_dir = a.r.run;
  opt.resume = a.r.resume;
  opt.init_weights = std::filesystem::is_directory(a.r.init) ? io::resolve_checkpoint(a.r.init) : a.r.init;
  opt.perceptual_weights = a.r.vgg19;
  opt.perceptual_input = a.vgg19_input;
  // torchrun / SLURM launch variables make this process one rank of a data-parallel run.
  const auto env = train::distributed_env_from_environment();
  opt.device = train::rank_device(parse_device(a.common.device), env);
  if (env.distributed()) opt.comm = std::make_shared<train::Communicator>(env, opt.device);
  opt.stop_after_steps = a.stop_after;
  if (config.training.eval_every > 0)
    opt.periodic_eval = eval::periodic_evaluation(config, a.r.data, a.r.run, opt.device);
  return opt;
}

// --stage tokenizer: the masked-image pretraining of the tokenizer, on the config's model and training settings.
void run_tokenizer_stage(const TrainArgs& a, const Config& config) {
  if (!a.r.init.empty())
    throw std::runtime_error(
        "train --stage tokenizer starts the tokenizer from scratch: --init is for the main stage "
        "that reads its output");
  train::TokenizerPretrainOptions opt;
  opt.data_root = a.r.data;
  opt.run_dir = a.r.run;
  opt.device = parse_device(a.common.device);
  log_kernel_paths();
  const auto r = train::pretrain_tokenizer(config, opt);
  std::cout << fmt::format("tokenizer pretrained for {} steps: masked-patch loss {:.4f} -> {:.4f}; weights {}\n",
                           r.steps, r.first_loss, r.last_loss, r.weights);
}

// --dry-run: the run's plan and its pre-flight checks (the global batch divides, the loss has what it needs), then
// exit; non-zero when the run itself would refuse to start.
void run_dry(const TrainArgs& a, const Config& config) {
  log_kernel_paths();
  const int64_t ranks = a.ranks > 0 ? a.ranks : train::distributed_env_from_environment().world_size;
  const auto plan = train::dry_run_plan(a.r, config, ranks, parse_device(a.common.device).str());
  std::cout << fmt::format("uplvsm train --dry-run --config {} ({} stage)\n", a.r.config_path, a.r.stage);
  for (const auto& line : train::describe_run_plan(plan)) std::cout << "  " << line << "\n";
  train::require_run_starts(plan);
  std::cout << "checks passed: this run would start\n";
}

void run_train(const TrainArgs& a) {
  apply_common_options(a.common);
  const auto config = train::train_config(a.r);
  if (a.dry_run) return run_dry(a, config);
  if (a.r.data.empty() || a.r.run.empty())
    throw std::runtime_error(
        fmt::format("train: {} is required (only --dry-run runs without it)", a.r.data.empty() ? "--data" : "--run"));
  if (a.r.stage == "tokenizer") return run_tokenizer_stage(a, config);
  auto r = train::train(config, train_options(a, config));
  std::cout << fmt::format("trained to step {} in {:.1f} s: loss {:.5f}, PSNR {:.2f} dB; checkpoint {}\n", r.step,
                           r.seconds, r.last_loss, r.last_psnr, r.last_checkpoint.empty() ? "-" : r.last_checkpoint);
  if (r.interrupted) throw std::runtime_error("training interrupted by a signal (resume with --resume auto)");
}

}  // namespace

void add_train_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "train",
      "Train UP-LVSM (no camera poses used) with the official recipe: AdamW + warmup/cosine, grad clip and "
      "skip rules; checkpoints <run>/checkpoints/ckpt_*.safetensors; --resume auto continues exactly. "
      "Data parallel: start one process per device with torchrun's variables (RANK, WORLD_SIZE, "
      "LOCAL_RANK, MASTER_ADDR, MASTER_PORT) or under SLURM; training.batch_size is per process and micro-batch, "
      "training.global_batch_size the scenes per update over all of them (the accumulation is derived). "
      "--dry-run prints the plan and exits.");
  auto a = std::make_shared<TrainArgs>();
  add_train_options(cmd, *a);
  cmd->callback([a] { run_train(*a); });
}

}  // namespace uplvsm::cli
