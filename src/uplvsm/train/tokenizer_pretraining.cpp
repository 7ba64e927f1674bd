#include "uplvsm/train/tokenizer_pretraining.h"

#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/io/safetensors.h"
#include "uplvsm/train/masked_image_modeling.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::train {

namespace fs = std::filesystem;

namespace {

// The tokenizer's ViT under Meta's DINOv2 names (what `--init` reads), with the mask token Meta files also carry.
void write_tokenizer(const train::MaskedImageModelImpl& mim, const std::string& path) {
  io::TensorMap tensors;
  for (const auto& p : mim.tokenizer->dino_vit->named_parameters()) tensors[p.key()] = p.value().detach().cpu();
  tensors["mask_token"] = mim.mask_token.detach().cpu();
  io::write_safetensors(path, tensors, {{"format", "dinov2"}, {"trained_by", "uplvsm train --stage tokenizer"}});
}

// One optimiser step on every image of the batch; returns the loss.
double pretrain_step(train::MaskedImageModelImpl& mim, torch::optim::AdamW& optimizer, const torch::Tensor& images,
                     const TokenizerPretrainOptions& opt, const TrainingConfig& tc) {
  const int64_t p = mim.patch_size, n = (images.size(2) / p) * (images.size(3) / p);
  auto mask = train::random_patch_mask(images.size(0), n, opt.mask_ratio).to(opt.device);
  optimizer.zero_grad();
  torch::Tensor loss;
  {
    Bf16Autocast amp(opt.device, tc.amp == Amp::Bf16);
    loss = mim.forward(images, mask);
  }
  loss.backward();
  if (tc.grad_clip_norm > 0) torch::nn::utils::clip_grad_norm_(mim.parameters(), tc.grad_clip_norm);
  adamw_step(optimizer);  // LibTorch's AdamW::step, in one pass
  return loss.item<double>();
}

}  // namespace

TokenizerPretrainResult pretrain_tokenizer(const Config& config, const TokenizerPretrainOptions& opt) {
  const auto& tc = config.training;
  TokenizerPretrainResult result;
  result.weights = (fs::path(opt.run_dir) / "tokenizer.safetensors").string();
  if (fs::exists(result.weights)) {
    spdlog::info("{} exists: the tokenizer stage of this run is done", result.weights);
    return result;
  }
  fs::create_directories(opt.run_dir);
  torch::manual_seed(static_cast<uint64_t>(tc.seed));
  train::MaskedImageModel mim(config.model);
  mim->to(opt.device);
  mim->train();
  auto optimizer = make_optimizer(*mim, tc);
  data::ChunkDataset dataset(opt.data_root, "train");
  data::TrainingLoader loader(dataset, loader_options(config, dataset, nullptr), 0);
  std::ofstream metrics(fs::path(opt.run_dir) / "metrics.jsonl");
  ProgressBar bar("tokenizer", tc.train_steps, "step");
  spdlog::info("tokenizer pretraining (masked image modelling, {:.0f} % of patches hidden): {} steps of {} images",
               100 * opt.mask_ratio, tc.train_steps, tc.batch_size * tc.num_views);
  for (int64_t step = 0; step < tc.train_steps; ++step) {
    const double lr = tc.lr * lr_lambda(step, tc.warmup, tc.train_steps);
    set_learning_rate(*optimizer, lr);
    const auto batch = loader.next();
    const auto images = batch.images.flatten(0, 1).to(opt.device);  // every view of every scene
    const double loss = pretrain_step(*mim, *optimizer, images, opt, tc);
    if (step == 0) result.first_loss = loss;
    result.last_loss = loss;
    result.steps = step + 1;
    if (!std::isfinite(loss))
      throw std::runtime_error(fmt::format("tokenizer pretraining: loss {} at step {}", loss, step + 1));
    if ((step + 1) % tc.log_every == 0 || step + 1 == tc.train_steps)
      metrics << nlohmann::json{{"step", step + 1}, {"loss", loss}, {"lr", lr}}.dump() << "\n" << std::flush;
    if (opt.progress) bar.update(step + 1, {{"loss", fmt::format("{:.4f}", loss)}});
  }
  if (opt.progress) bar.finish();
  write_tokenizer(*mim, result.weights);
  spdlog::info("tokenizer pretraining: loss {:.4f} -> {:.4f}; weights {} (use with --init)", result.first_loss,
               result.last_loss, result.weights);
  return result;
}

}  // namespace uplvsm::train
