// The held-out evaluation a training run makes every training.eval_every steps (a monitor: it selects no weights).
#pragma once
#include <torch/torch.h>

#include "uplvsm/core/config.h"
#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

// As the official train.py's evaluation: the run's precision and target poses, and its pose noise on the cameras the
// model reads (the official adds `noise_scale` there too: train.py:176 -> uplvsm.py:270 -> data_utils.py:238-250 at
// d490397, with no train / eval condition; it moves only the posed variants' scores), seeded by training.seed; on
// the first eval.max_scenes scenes of the index (16 when 0). The caller sets index_path and out_dir.
EvalOptions training_evaluation_options(const Config& config, model::TargetPoses target_poses, torch::Device device);

}  // namespace uplvsm::eval
