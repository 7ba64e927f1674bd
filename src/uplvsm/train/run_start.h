// How a training run starts: from a checkpoint (its weights, AdamW state and training state), or
// new, optionally from weights (--init: an UP-LVSM file loaded strictly, or DINOv2 into the image tokenizer), with
// the camera-control stage's pose mapper fitted by least squares first when the file lacks it.
#pragma once
#include <torch/torch.h>

#include <memory>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::train {

// The model on its device in train mode, its optimiser and the state to go on from (a checkpoint or step 0).
struct ModelStart {
  model::NovelViewModel net;
  std::unique_ptr<torch::optim::AdamW> optimizer;
  TrainState state;
};

ModelStart start_model(const Config& config, const TrainOptions& options, const std::string& checkpoint_dir);

// Whether `train` of run_dir with `resume` ("auto", "none" or a file) goes on from a checkpoint rather than starting a
// new run (a look at <run>/checkpoints, nothing read).
bool run_resumes(const std::string& run_dir, const std::string& resume);

}  // namespace uplvsm::train
