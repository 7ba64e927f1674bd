// The official evaluation's pose noise. The authors' ProcessData.forward (src/utils/data_utils.py:236-250) runs in
// evaluation as in training, so with `unposed.noise_scale` > 0 their test cameras are noisy too. This puts the same
// noise, the training loader's function (data::with_pose_noise), on one evaluation scene's dataset cameras: in the
// official scene frame over its context and target views, after the input/target split, inputs and targets drawn
// apart, from a stream that depends only on (seed, scene key).
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::eval {

// Throws std::invalid_argument naming --pose-noise-std unless std is a finite number >= 0.
void check_pose_noise_std(double std);

// Whether a model rendering with `target_poses` reads dataset cameras, the only thing the noise moves: the posed
// models always do (inputs and targets); UP-LVSM does with mapper or dataset target poses (its inputs' and targets'
// cameras give the targets' real poses), never with the estimator's (it reads only images, as officially).
bool pose_noise_reaches_model(model::TargetPoses target_poses);

// The seed of one scene's stream: a function of (seed, key) only, so the draws do not depend on the batch, the
// shard, the thread count or the order of the index.
uint64_t pose_noise_scene_seed(uint64_t seed, const std::string& key);

struct ToldCameras {
  torch::Tensor inputs;   // [vi, 4, 4] float32, in the official scene frame
  torch::Tensor targets;  // [vt, 4, 4]
};

// One scene's cameras c2w [vi + vt, 4, 4] (context views, then targets) as a posed model is told them: normalised over
// all of them (geometry::official_scene_normalize, what the posed models do to clean evaluation cameras), split, then
// N(0, std^2) on the (t, q_xyzw) encodings of the inputs and, drawn next from the same stream, of the targets.
ToldCameras noisy_scene_cameras(const torch::Tensor& c2w, int64_t num_inputs, double std, uint64_t seed,
                                const std::string& key);

// What metrics.json records under "pose_noise": {std, seed (when std > 0), reaches_model, cameras (in words)}.
nlohmann::json pose_noise_record(double std, uint64_t seed, model::TargetPoses target_poses);

}  // namespace uplvsm::eval
