// `uplvsm fit-mapper`: camera control for a trained UP-LVSM without fine-tuning it (train/mapper_run.h, fitted as
// train/mapper_fitting.h says): a pose mapper fitted to the model from posed scenes and saved apart from it, for
// `render|eval|serve --mapper`; and `uplvsm study mapper-scenes`, how few posed scenes such a fit needs
// (study/mapper_scenes.h).
#include <cmath>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/eval/training_evaluation.h"
#include "uplvsm/study/mapper_scenes.h"
#include "uplvsm/train/mapper_run.h"

namespace uplvsm::cli {

namespace {

// What fit-mapper and study mapper-scenes share: the model, the posed scenes, the mapper and how it is fitted.
template <typename Options>
struct FitArgs {
  CommonOptions common;
  ModelSource model;
  Amp amp = Amp::None;
  Options run;
  // The parsed flags with the model source, precision and device in.
  Options options() const {
    auto o = run;
    o.checkpoint = model.checkpoint, o.config = model.config, o.bf16 = amp == Amp::Bf16;
    o.device = parse_device(common.device);
    return o;
  }
};

template <typename Options>
void add_fit_options(CLI::App* cmd, FitArgs<Options>& f) {
  add_common_options(cmd, f.common);
  add_model_options(cmd, f.model);
  auto& a = f.run;
  cmd->add_option("--data", a.data,
                  "posed scenes: a dataset root (pixelSplat chunks or the LVSM layout; COLMAP / transforms.json "
                  "folders via `uplvsm dataset import`)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a.split, "dataset split of the posed scenes")->capture_default_str();
  add_amp_option(cmd, f.amp, "the frozen model's forward precision: none (fp32) or bf16 autocast");
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

struct FitMapperArgs : FitArgs<train::FitMapperOptions> {
  std::string eval_data, eval_out;
  int64_t eval_scenes = 0;
};

void run_fit_mapper(const FitMapperArgs& a) {
  apply_common_options(a.common);
  const auto options = a.options();
  auto [report, s] = train::fit_mapper(options);
  std::cout << fmt::format(
      "fitted a {} pose mapper to {} views of {} scenes in {:.1f} s (RMS {:.4f} latent units{}; "
      "the least-squares linear map's {:.4f}) -> {}\n",
      options.kind, report.calibration_views, report.scenes, report.seconds, report.fit_rms,
      std::isfinite(report.held_out_rms)
          ? fmt::format(", {:.4f} on {} held-out scenes", report.held_out_rms, report.held_out_scenes.size())
          : std::string(),
      report.least_squares_rms, options.out);
  if (a.eval_data.empty()) return;
  const auto out = a.eval_out.empty() ? options.out + ".eval" : a.eval_out;
  const auto summary =
      eval::evaluate_mapper(s.net, s.config, a.eval_data, a.eval_scenes, options.bf16, options.device, out,
                            {{"checkpoint", options.checkpoint}, {"mapper", options.out}, {"data", a.eval_data}});
  const auto& m = summary.scores.model;
  std::cout << fmt::format(
      "held-out: {} scenes at real cameras through the mapper: PSNR {:.2f} dB, SSIM {:.4f} "
      "(copy-nearest {:.2f} dB) -> {}/metrics.json\n",
      summary.scenes, m.psnr, m.ssim, summary.scores.copy_nearest.psnr, out);
}

struct MapperScenesArgs : FitArgs<train::MapperRunOptions> {
  std::string eval_data, out;
  std::vector<int64_t> counts = {1, 4, 16, 64, 256};
  int64_t eval_scenes = 0;
};

void run_mapper_scenes(const MapperScenesArgs& a) {
  apply_common_options(a.common);
  const auto options = a.options();
  study::MapperScenesOptions opt;
  opt.scene_counts = a.counts;
  opt.eval_scenes = a.eval_scenes;
  opt.out_dir = a.out;
  const auto rows = study::run_mapper_scenes_study(options, a.eval_data, opt);
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
  cmd->add_option("--out", a->run.out, "the mapper file to write (safetensors; the model file is not changed)")
      ->required();
  cmd->add_option("--scenes", a->run.scenes, "use the split's first N scenes only (0: all)")
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
