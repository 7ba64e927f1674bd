// The held-out evaluations of what training makes: a run's every training.eval_every steps (a monitor: it selects no
// weights), and a pose mapper's fitted by fit-mapper (train/mapper_run.h).
#pragma once
#include <torch/torch.h>

#include <functional>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

// As the official train.py's evaluation: the run's precision and target poses, and its pose noise on the cameras the
// model reads (the official adds `noise_scale` there too: train.py:176 -> uplvsm.py:270 -> data_utils.py:238-250 at
// d490397, with no train / eval condition; it moves only the posed variants' scores), seeded by training.seed; on
// the first eval.max_scenes scenes of the index (16 when 0). The caller sets index_path and out_dir.
EvalOptions training_evaluation_options(const Config& config, model::TargetPoses target_poses, torch::Device device);

// The trainer's periodic_eval hook (train::TrainOptions) for a run of `config` on `data` into `run`: the test split's
// evaluation index with the options above; results in <run>/eval/step_NNNNNNN/. Empty (with a warning) when
// <data>/evaluation_index.json does not exist.
std::function<nlohmann::json(model::NovelViewModel&, int64_t)> periodic_evaluation(const Config& config,
                                                                                   const std::string& data,
                                                                                   const std::string& run,
                                                                                   torch::Device device);

// A fitted pose mapper's held-out score (fit-mapper --eval-data): `net` (with the mapper attached) on the test split
// of `data` and its evaluation index, at real cameras through the mapper, at most max_scenes scenes (0: all), four
// drawn, into out_dir; `extra` is recorded in metrics.json.
EvalSummary evaluate_mapper(model::NovelViewModel& net, const Config& config, const std::string& data,
                            int64_t max_scenes, bool bf16, torch::Device device, const std::string& out_dir,
                            const nlohmann::json& extra);

}  // namespace uplvsm::eval
