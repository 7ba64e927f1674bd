#include "uplvsm/eval/training_evaluation.h"

namespace uplvsm::eval {

EvalOptions training_evaluation_options(const Config& config, model::TargetPoses target_poses, torch::Device device) {
  EvalOptions opt;
  opt.max_scenes = config.eval.max_scenes > 0 ? config.eval.max_scenes : 16;
  opt.device = device;
  opt.num_visualised = 2;
  opt.bf16 = config.training.amp == Amp::Bf16;
  opt.target_poses = target_poses;
  opt.pose_noise_std = config.training.pose_noise_std;
  opt.pose_noise_seed = static_cast<uint64_t>(config.training.seed);
  return opt;
}

}  // namespace uplvsm::eval
