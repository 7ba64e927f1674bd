// `uplvsm eval` as library calls: the evaluator's options from what a user asks of a checkpoint (its protocol, pose
// refinement and noise, LPIPS weights, what metrics.json records), and the jitter along the same scenes' camera
// paths written beside metrics.json. Sharding over processes is the caller's (its communicator is train/'s).
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/camera_jitter.h"
#include "uplvsm/eval/evaluator.h"

namespace uplvsm::eval {

struct EvalRequest {
  std::string checkpoint, mapper;           // recorded; a --mapper makes auto target poses the mapper's
  std::string data, split = "test", index;  // index: empty, <data>/evaluation_index.json
  std::string out;                          // output directory
  int64_t max_scenes = 0, batch = 4, visualise = 8;
  TargetPoses target_poses = TargetPoses::Auto;  // auto: as trained (config.training.target_poses)
  PoseRefinement refinement;
  double pose_noise_std = 0;
  uint64_t seed = 0;  // of the pose noise
  bool bf16 = false;
  std::string lpips_net = "vgg", lpips_backbone, lpips_lin;  // no backbone: LPIPS unavailable
};

// The evaluator's options for `net` (loaded with `config`) on `device`, LPIPS loaded when asked for.
EvalOptions evaluation_options(const EvalRequest& request, const Config& config, model::NovelViewModel& net,
                               torch::Device device);

// Jitter along the request's scenes' camera paths (camera control needed), written to <out>/jitter.json.
JitterSummary write_jitter(const EvalRequest& request, model::NovelViewModel& net, const data::ChunkDataset& dataset,
                           const data::PreprocessOptions& prep, torch::Device device);

}  // namespace uplvsm::eval
