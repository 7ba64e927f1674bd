// `uplvsm train`: trains UP-LVSM from images alone on a pixelSplat-format dataset; resumable.
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/config.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::cli {

void add_train_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "train", "Train UP-LVSM (no camera poses used) with the official recipe: AdamW + warmup/cosine, grad clip and "
               "skip rules; checkpoints <run>/checkpoints/ckpt_*.safetensors; --resume auto continues exactly. "
               "Data parallel: start one process per device with torchrun's variables (RANK, WORLD_SIZE, "
               "LOCAL_RANK, MASTER_ADDR, MASTER_PORT) or under SLURM; training.batch_size is per process.");
  struct Args {
    CommonOptions common;
    std::string config, data, run, resume = "auto", init, vgg19, amp;
    int64_t steps = -1, stop_after = -1;
  };
  auto a = std::make_shared<Args>();
  add_common_options(cmd, a->common);
  cmd->add_option("--config", a->config, "config JSON (configs/tiny.json, configs/paper_x224.json)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--data", a->data, "dataset root (pixelSplat chunks with a train/ split)")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--run", a->run, "run directory (config snapshot, metrics.jsonl, checkpoints/)")->required();
  cmd->add_option("--resume", a->resume, "auto (latest checkpoint in --run, if any), none, or a checkpoint path")
      ->capture_default_str();
  cmd->add_option("--init", a->init,
                  "start a new run from these weights: UP-LVSM (ours or official, loaded strictly) or DINOv2 "
                  "(Meta .pth or HuggingFace safetensors, into the image tokenizer, as the official code does)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--vgg19", a->vgg19,
                  "VGG19 weights for the perceptual loss (torchvision features.N.*: torchvision vgg19 .pth, or the "
                  "<out>.vgg19.safetensors that `uplvsm convert` extracts from an official checkpoint); without it "
                  "a config with training.perceptual_loss_weight > 0 trains with MSE only")
      ->check(CLI::ExistingFile);
  cmd->add_option("--amp", a->amp, "override training.amp: none (fp32) or bf16 (autocast, fp32 master weights)")
      ->check(CLI::IsMember({"none", "bf16"}));
  cmd->add_option("--steps", a->steps, "override training.train_steps");
  cmd->add_option("--stop-after", a->stop_after, "stop after this many steps of this invocation (checkpointed)");
  cmd->callback([a] {
    apply_common_options(a->common);
    auto config = load_config(a->config);
    if (a->steps > 0) config.training.train_steps = a->steps;
    if (!a->amp.empty()) config.training.amp = a->amp;
    train::TrainOptions opt;
    opt.data_root = a->data;
    opt.run_dir = a->run;
    opt.resume = a->resume;
    opt.init_weights = a->init;
    opt.perceptual_weights = a->vgg19;
    // torchrun / SLURM launch variables make this process one rank of a data-parallel run.
    const auto env = train::distributed_env_from_environment();
    opt.device = train::rank_device(parse_device(a->common.device), env);
    if (env.distributed()) opt.comm = std::make_shared<train::Communicator>(env, opt.device);
    opt.stop_after_steps = a->stop_after;
    auto r = train::train(config, opt);
    std::cout << fmt::format("trained to step {} in {:.1f} s: loss {:.5f}, PSNR {:.2f} dB; checkpoint {}\n", r.step,
                             r.seconds, r.last_loss, r.last_psnr, r.last_checkpoint.empty() ? "-" : r.last_checkpoint);
    if (r.interrupted) throw std::runtime_error("training interrupted by a signal (resume with --resume auto)");
  });
}

}  // namespace uplvsm::cli
