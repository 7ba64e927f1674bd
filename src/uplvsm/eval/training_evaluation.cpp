#include "uplvsm/eval/training_evaluation.h"

#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/data/chunk_dataset.h"

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

std::function<nlohmann::json(model::NovelViewModel&, int64_t)> periodic_evaluation(const Config& config,
                                                                                   const std::string& data,
                                                                                   const std::string& run,
                                                                                   torch::Device device) {
  const auto index = std::filesystem::path(data) / "evaluation_index.json";
  if (!std::filesystem::exists(index)) {
    spdlog::warn("training.eval_every is set but {} does not exist: no periodic evaluation", index.string());
    return {};
  }
  return [=](model::NovelViewModel& net, int64_t step) {
    data::ChunkDataset dataset(data, "test");
    const auto prep = data::preprocess_options(config);
    auto opt =
        training_evaluation_options(config, model::resolve_target_poses(config.training.target_poses, *net), device);
    opt.index_path = index.string();
    opt.out_dir = (std::filesystem::path(run) / "eval" / fmt::format("step_{:07d}", step)).string();
    auto summary = evaluate(net, dataset, prep, opt);
    const auto& model_row = summary.scores.model;
    spdlog::info("step {}: held-out PSNR {:.2f} dB, SSIM {:.4f}, edges {:.3f} on {} scenes (copy-nearest {:.2f} dB)",
                 step, model_row.psnr, model_row.ssim, model_row.grad_ratio, summary.scenes,
                 summary.scores.copy_nearest.psnr);
    return nlohmann::json{{"psnr", model_row.psnr},
                          {"ssim", model_row.ssim},
                          {"grad_ratio", model_row.grad_ratio},
                          {"scenes", summary.scenes},
                          {"copy_nearest_psnr", summary.scores.copy_nearest.psnr},
                          {"dir", opt.out_dir}};
  };
}

EvalSummary evaluate_mapper(model::NovelViewModel& net, const Config& config, const std::string& data,
                            int64_t max_scenes, bool bf16, torch::Device device, const std::string& out_dir,
                            const nlohmann::json& extra) {
  data::ChunkDataset dataset(data, "test");
  EvalOptions opt;
  opt.max_scenes = max_scenes;
  opt.device = device;
  opt.num_visualised = 4;
  opt.bf16 = bf16;
  opt.target_poses = model::TargetPoses::Mapper;
  opt.out_dir = out_dir;
  opt.extra = extra;
  return evaluate(net, dataset, data::preprocess_options(config), opt);
}

}  // namespace uplvsm::eval
