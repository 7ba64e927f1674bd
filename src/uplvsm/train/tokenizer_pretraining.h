// `uplvsm train --stage tokenizer`: self-supervised pretraining of the image tokenizer by masked image modelling
// (train/masked_image_modeling.h) on the training split's images, the paper's recipe with our own pretrained
// features where it starts from Meta's DINOv2. The result is a DINOv2-format file (Meta names) that a UP-LVSM run
// reads with `--init`, exactly as it would read Meta's weights. No camera is read.
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

struct TokenizerPretrainOptions {
  std::string data_root, run_dir;
  torch::Device device = torch::kCPU;
  double mask_ratio = 0.6;  // SimMIM's ratio; every image of every view of a batch is one sample
  bool progress = true;
};

struct TokenizerPretrainResult {
  int64_t steps = 0;
  double first_loss = 0, last_loss = 0;  // the masked-patch MSE of the first and last step
  std::string weights;                   // <run>/tokenizer.safetensors
};

// training.train_steps steps of training.batch_size scenes x training.num_views images each, AdamW with the
// trainer's schedule and lr, bf16 when training.amp says so; writes metrics.jsonl ({step, loss, lr}) and, at the
// end, tokenizer.safetensors (the ViT under Meta's names, plus mask_token). Deterministic in training.seed; a
// finished run (the file exists) is not redone.
TokenizerPretrainResult pretrain_tokenizer(const Config& config, const TokenizerPretrainOptions& opt);

}  // namespace uplvsm::train
