// `uplvsm fit-mapper`: camera control for a trained UP-LVSM without fine-tuning it (train/mapper_fitting.h): a pose
// mapper fitted to the model from posed scenes and saved apart from it, for `render|eval|serve --mapper`; and
// `uplvsm study mapper-scenes`, how few posed scenes such a fit needs (study/mapper_scenes.h).
#include <cmath>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/pose_mapper_file.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/study/mapper_scenes.h"
#include "uplvsm/train/mapper_fitting.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::cli {

namespace {

// What fit-mapper and study mapper-scenes share: the model, the posed scenes, the mapper and how it is fitted.
struct FitArgs {
  CommonOptions common;
  ModelSource model;
  std::string data, split = "train", kind = "mlp";
  Amp amp = Amp::None;
  int64_t hidden = 128, batch = 8, targets = 0, min_frame_dist = 0, max_frame_dist = 0;
  double pose_noise_std = 0;
  uint64_t seed = 0;
  train::MapperFitOptions fit;
};

void add_fit_options(CLI::App* cmd, FitArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
  cmd->add_option("--data", a.data,
                  "posed scenes: a dataset root (pixelSplat chunks or the LVSM layout; COLMAP / transforms.json "
                  "folders via `uplvsm dataset import`)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a.split, "dataset split of the posed scenes")->capture_default_str();
  add_amp_option(cmd, a.amp, "the frozen model's forward precision: none (fp32) or bf16 autocast");
  cmd->add_option("--kind", a.kind,
                  "mapper: mlp (the paper's linear map plus a small MLP that also reads the latent poses the "
                  "estimator gives the two input views) or linear (the paper's C = A C_real + b)")
      ->check(CLI::IsMember({"linear", "mlp"}))
      ->capture_default_str();
  cmd->add_option("--hidden", a.hidden, "mlp: width of its two hidden layers")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  cmd->add_option("--views", a.fit.calibration_views, "posed target views the mapper is fitted on")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--steps", a.fit.regression_steps, "mlp: full-batch Adam steps on those views (pose space)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--lr", a.fit.regression_lr, "mlp: peak learning rate (linear warmup, cosine decay)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--batch", a.batch, "samples encoded at once")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--targets", a.targets, "target views per sample (0: the model config's training views)");
  cmd->add_option("--min-frame-dist", a.min_frame_dist, "input frames at least this far apart (0: the config's)");
  cmd->add_option("--max-frame-dist", a.max_frame_dist, "input frames at most this far apart (0: the config's)");
  cmd->add_option("--seed", a.seed, "seed of the view sampling (0: the config's training seed)");
  // Reconstructed cameras are not exact: a mapper fitted on noisy ones shows what such logs do to the map.
  cmd->add_option("--pose-noise-std", a.pose_noise_std,
                  "fit on cameras with N(0, S^2) added to their 7-D (t, q) encoding, inputs and targets apart, as "
                  "the training loader's pose-noise study draws it (SfM-like camera error; 0: the dataset's cameras)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
}

// The view sampling: the checkpoint's training views unless overridden (an official checkpoint carries the paper's).
data::LoaderOptions fit_loader_options(const FitArgs& a, const Config& config, const data::ChunkDataset& dataset) {
  auto lo = train::loader_options(config, dataset, nullptr);
  lo.batch_size = a.batch;
  lo.micro_batches_per_step = 1;
  lo.pose_noise_std = a.pose_noise_std;
  lo.chunks_per_shuffle = 0;
  if (a.targets > 0) {
    lo.num_target_views = static_cast<int>(a.targets);
    lo.num_views = lo.num_input_views + lo.num_target_views;
  }
  if (a.min_frame_dist > 0) lo.min_frame_dist = static_cast<int>(a.min_frame_dist);
  if (a.max_frame_dist > 0) lo.max_frame_dist = static_cast<int>(a.max_frame_dist);
  lo.frame_dist_curriculum_steps = 0;
  if (a.seed > 0) lo.seed = a.seed;
  return lo;
}

// The model (an UP-LVSM), its config and the fit's options, ready to fit on `dataset`.
struct FitSetup {
  Config config;
  model::NovelViewModel net{nullptr};
  model::UPLVSM up{nullptr};
  torch::Device device = torch::kCPU;
};

FitSetup load_for_fit(FitArgs& a, const data::ChunkDataset& dataset) {
  FitSetup s;
  s.device = parse_device(a.common.device);
  s.net = model::load_model_with_config_file(a.model.checkpoint, a.model.config, s.device, &s.config);
  s.up = model::require_uplvsm(s.net, "fit-mapper (camera control through latent poses)");
  a.fit.loader = fit_loader_options(a, s.config, dataset);
  a.fit.device = s.device;
  a.fit.bf16 = a.amp == Amp::Bf16;
  return s;
}

model::PoseMapperOptions mapper_options(const FitArgs& a) { return {model::parse_pose_mapper_kind(a.kind), a.hidden}; }

struct FitMapperArgs : FitArgs {
  std::string out, eval_data, eval_out;
  int64_t scenes = 0, eval_scenes = 0;
};

void evaluate_fitted(const FitMapperArgs& a, FitSetup& s) {
  data::ChunkDataset dataset(a.eval_data, "test");
  eval::EvalOptions opt;
  opt.max_scenes = a.eval_scenes;
  opt.device = s.device;
  opt.num_visualised = 4;
  opt.bf16 = a.amp == Amp::Bf16;
  opt.target_poses = model::TargetPoses::Mapper;
  opt.out_dir = a.eval_out.empty() ? a.out + ".eval" : a.eval_out;
  opt.extra = {{"checkpoint", a.model.checkpoint}, {"mapper", a.out}, {"data", a.eval_data}};
  auto summary = eval::evaluate(s.net, dataset, data::preprocess_options(s.config), opt);
  const auto& m = summary.scores.model;
  std::cout << fmt::format(
      "held-out: {} scenes at real cameras through the mapper: PSNR {:.2f} dB, SSIM {:.4f} "
      "(copy-nearest {:.2f} dB) -> {}/metrics.json\n",
      summary.scenes, m.psnr, m.ssim, summary.scores.copy_nearest.psnr, opt.out_dir);
}

void run_fit_mapper(FitMapperArgs& a) {
  apply_common_options(a.common);
  data::ChunkDataset dataset(a.data, a.split);
  auto s = load_for_fit(a, dataset);
  a.fit.loader.max_scenes = a.scenes;
  model::PoseMapper mapper(mapper_options(a));
  auto report = train::fit_mapper_to_model(*s.up, *mapper, dataset, a.fit);
  auto fit = report.to_json();
  fit["kind"] = a.kind;
  fit["data"] = a.data;
  fit["checkpoint"] = a.model.checkpoint;
  model::save_pose_mapper(a.out, *mapper, model::model_fingerprint(*s.up), fit);
  std::cout << fmt::format(
      "fitted a {} pose mapper to {} views of {} scenes in {:.1f} s (RMS {:.4f} latent units{}; "
      "the least-squares linear map's {:.4f}) -> {}\n",
      a.kind, report.calibration_views, report.scenes, report.seconds, report.fit_rms,
      std::isfinite(report.held_out_rms)
          ? fmt::format(", {:.4f} on {} held-out scenes", report.held_out_rms, report.held_out_scenes.size())
          : std::string(),
      report.least_squares_rms, a.out);
  if (a.eval_data.empty()) return;
  s.up->attach_pose_mapper(mapper);
  evaluate_fitted(a, s);
}

struct MapperScenesArgs : FitArgs {
  std::string eval_data, out;
  std::vector<int64_t> counts = {1, 4, 16, 64, 256};
  int64_t eval_scenes = 0;
};

void run_mapper_scenes(MapperScenesArgs& a) {
  apply_common_options(a.common);
  data::ChunkDataset posed(a.data, a.split), held_out(a.eval_data, "test");
  auto s = load_for_fit(a, posed);
  study::MapperScenesOptions opt;
  opt.scene_counts = a.counts;
  opt.mapper = mapper_options(a);
  opt.fit = a.fit;
  opt.eval_scenes = a.eval_scenes;
  opt.out_dir = a.out;
  auto rows = study::run_mapper_scenes(s.net, posed, held_out, data::preprocess_options(s.config), opt);
  for (const auto& r : rows)
    std::cout << fmt::format("{:>6} scenes: PSNR {:.2f} dB, SSIM {:.4f} ({} views, fitted in {:.1f} s)\n", r.scenes,
                             r.psnr, r.ssim, r.fit.calibration_views, r.fit.seconds);
  std::cout << "-> " << a.out << "/mapper_scenes.json, mapper_scenes.csv, psnr.png\n";
}

}  // namespace

void add_fit_mapper_command(CLI::App& app) {
  auto a = std::make_shared<FitMapperArgs>();
  auto* cmd = app.add_subcommand(
      "fit-mapper",
      "Camera control for a trained UP-LVSM (the authors' checkpoints included) without fine-tuning it: a pose "
      "mapper from real cameras to the latent poses the model's estimator reads, fitted on posed scenes in pose "
      "space (minutes), saved apart from the model for render|eval|serve --mapper");
  add_fit_options(cmd, *a);
  cmd->add_option("--out", a->out, "the mapper file to write (safetensors; the model file is not changed)")->required();
  cmd->add_option("--scenes", a->scenes, "use the split's first N scenes only (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--eval-data", a->eval_data,
                  "after fitting, score the mapper on this dataset's held-out scenes (its evaluation index)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--eval-out", a->eval_out, "where that evaluation writes (default <out>.eval)");
  cmd->add_option("--eval-scenes", a->eval_scenes, "score at most this many scenes (0: all)");
  cmd->callback([a] { run_fit_mapper(*a); });
}

void add_mapper_scenes_command(CLI::App& study) {
  auto a = std::make_shared<MapperScenesArgs>();
  auto* cmd = study.add_subcommand(
      "mapper-scenes",
      "How few posed scenes a fitted pose mapper needs: fit-mapper on the first N scenes of --data for each N, each "
      "scored at real cameras on --eval-data's held-out scenes; mapper_scenes.json/.csv and psnr.png");
  add_fit_options(cmd, *a);
  cmd->add_option("--eval-data", a->eval_data, "held-out scenes (the test split and its evaluation index)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--scenes", a->counts, "the scene counts")->capture_default_str();
  cmd->add_option("--eval-scenes", a->eval_scenes, "score at most this many scenes (0: all)");
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] { run_mapper_scenes(*a); });
}

}  // namespace uplvsm::cli
