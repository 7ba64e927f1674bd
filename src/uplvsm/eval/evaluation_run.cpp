// `uplvsm eval`'s options and jitter report (eval/evaluation_run.h).
#include "uplvsm/eval/evaluation_run.h"

#include <filesystem>

#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/checkpoint_io.h"

namespace uplvsm::eval {

EvalOptions evaluation_options(const EvalRequest& a, const Config& config, model::NovelViewModel& net,
                               torch::Device device) {
  EvalOptions opt;
  opt.index_path = a.index;
  opt.max_scenes = a.max_scenes;
  opt.batch_size = a.batch;
  opt.device = device;
  opt.num_visualised = a.visualise;
  opt.out_dir = a.out;
  opt.pose_refinement = a.refinement;
  opt.pose_noise_std = a.pose_noise_std;
  opt.pose_noise_seed = a.seed;
  opt.bf16 = a.bf16;
  // auto: as trained (a UP-LVSM trained from dataset cameras has an untrained estimator).
  // auto with --mapper: the mapper given for it.
  auto choice = a.target_poses;
  if (choice == TargetPoses::Auto) choice = a.mapper.empty() ? config.training.target_poses : TargetPoses::Mapper;
  opt.target_poses = model::resolve_target_poses(choice, *net);
  if (!a.lpips_backbone.empty()) {
    opt.lpips = load_lpips(parse_lpips_net(a.lpips_net), a.lpips_backbone, a.lpips_lin);
    opt.lpips->to(device);
  }
  opt.extra = {{"checkpoint", io::resolve_checkpoint(a.checkpoint)},
               {"mapper", a.mapper},
               {"data", a.data},
               {"split", a.split},
               {"config", config.name},
               {"variant", to_string(config.model.variant)},
               {"target_poses", uplvsm::to_string(opt.target_poses)}};
  if (a.refinement.steps > 0) opt.extra["pose_refinement"] = {{"steps", a.refinement.steps}, {"lr", a.refinement.lr}};
  return opt;
}

JitterSummary write_jitter(const EvalRequest& a, model::NovelViewModel& net, const data::ChunkDataset& dataset,
                           const data::PreprocessOptions& prep, torch::Device device) {
  JitterOptions opt;
  opt.index_path = a.index;
  opt.max_scenes = a.max_scenes;
  opt.device = device;
  opt.bf16 = a.bf16;
  auto j = measure_jitter(net, dataset, prep, opt);
  auto out = j.to_json();
  out["mapper"] = a.mapper;
  out["checkpoint"] = a.checkpoint;
  std::filesystem::create_directories(a.out);
  const auto text = out.dump(2) + "\n";
  io::write_file_atomic((std::filesystem::path(a.out) / "jitter.json").string(), text.data(), text.size());
  return j;
}

}  // namespace uplvsm::eval
