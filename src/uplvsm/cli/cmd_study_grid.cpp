// `uplvsm study scaling` and `uplvsm study pose-noise`: the flags of the grid studies (study/grid_runner.h runs
// them).
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/study/grid_runner.h"

namespace uplvsm::cli {

namespace {

struct GridArgs {
  CommonOptions common;
  study::GridOptions study;
};

void add_grid_options(CLI::App* cmd, GridArgs& g) {
  add_common_options(cmd, g.common);
  auto& a = g.study;
  cmd->add_option("--config", a.configs,
                  "one config per series (model variant), e.g. configs/tiny.json "
                  "configs/tiny_ptlvsm.json configs/tiny_lvsm.json")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--data", a.data, "dataset root: train/ for training, test/ + evaluation_index.json for scoring")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", a.out, "study directory (runs/, table.md, table.csv, *.png, README.md)")->required();
  cmd->add_option("--steps", a.steps, "training steps of every run (default: each config's training.train_steps)");
  cmd->add_option("--set", a.overrides,
                  "section.field=value for every config, as for train (e.g. "
                  "training.eval_every=500 for held-out curves)");
  cmd->add_option("--seeds", a.seeds, "training seeds: every run once per seed, the table their mean ± half range")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--eval-scenes", a.eval_scenes, "test scenes scored per run (0: the whole index)")
      ->capture_default_str();
  cmd->add_option("--reference", a.reference,
                  "published numbers to plot beside ours (CSV: series,setting,x,psnr,ssim,lpips), e.g. "
                  "docs/research/data/paper_objaverse_scaling.csv")
      ->check(CLI::ExistingFile);
  cmd->add_option("--reference-title", a.reference_title, "the reference plots' title")->capture_default_str();
  auto* report_only =
      cmd->add_flag("--report-only", a.report_only,
                    "write the table, plots and curves from the runs done so far (a run without result.json reads "
                    "'(not run)'; an unfinished run's curve is shown as far as it got); nothing trains");
  cmd->add_option("--from-table", a.from_table,
                  "with --report-only: each run's scores from this table.csv of the same study (matched by series, "
                  "setting and seed) instead of runs/, to redraw a study whose runs are on another machine")
      ->check(CLI::ExistingFile)
      ->needs(report_only);
  cmd->add_option("--vgg19", a.vgg19, "VGG19 weights for the perceptual loss (as for `uplvsm train`)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--init", a.init,
                  "starting weights of every run, as for `uplvsm train` (the pretrained DINOv2 the full-size "
                  "configs' tokenizer needs)")
      ->check(CLI::ExistingFile);
  add_vgg19_input_option(cmd, a.vgg19_input);
  cmd->add_option("--lpips-net", a.lpips_net, "LPIPS backbone: vgg or alex")
      ->check(CLI::IsMember({"vgg", "alex"}))
      ->capture_default_str();
  auto* backbone = cmd->add_option("--lpips-backbone", a.lpips_backbone, "LPIPS backbone weights (as for eval)")
                       ->check(CLI::ExistingFile);
  cmd->add_option("--lpips-lin", a.lpips_lin, "LPIPS lin weights (as for eval)")
      ->check(CLI::ExistingFile)
      ->needs(backbone);
  backbone->needs("--lpips-lin");
}

// Runs the plan made from the parsed flags and prints the table.
void run(const GridArgs& a, const std::function<study::GridPlan(const study::GridOptions&)>& plan) {
  apply_common_options(a.common);
  auto options = a.study;
  options.device = parse_device(a.common.device);
  const auto result = study::run_grid(plan(options), options);
  std::cout << "\n" << result.table << fmt::format("\nstudy results -> {}/README.md\n", options.out);
}

void add_scaling(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "scaling",
      "Scalability study (paper Table 3): train each --config on nested subsets of the training scenes "
      "(the first N of the train split) with the same step budget, score all on one test set; table with "
      "the average gain per 4x data (the paper's least-squares slope) and its interval, plots vs scenes (log x)");
  auto a = std::make_shared<GridArgs>();
  auto subsets = std::make_shared<std::vector<std::string>>();
  auto growth = std::make_shared<double>(1.0);
  auto noise = std::make_shared<double>(0.0);
  add_grid_options(cmd, *a);
  cmd->add_option("--subsets", *subsets, "training scenes per subset, small to large, e.g. 25 100 400 or full")
      ->required();
  cmd->add_option("--steps-growth", *growth,
                  "training steps multiplied by this from one subset to the next "
                  "(1: the same budget for all)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--noise-std", *noise, "pose noise on the training cameras of every run (training.pose_noise_std)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->callback([a, subsets, growth, noise] {
    run(*a, [&](const study::GridOptions& o) { return study::scaling_plan(o, *subsets, *growth, *noise); });
  });
}

void add_pose_noise(CLI::App& study) {
  auto* cmd = study.add_subcommand(
      "pose-noise",
      "Pose-noise study (paper appendix): train each --config with Gaussian noise of each level added to the "
      "(translation, quaternion) encodings of its training cameras as the official noise_scale does, score all "
      "with clean test cameras. UP-LVSM never reads training poses: it is trained once and stands at every level");
  auto a = std::make_shared<GridArgs>();
  auto stds = std::make_shared<std::vector<double>>();
  auto variances = std::make_shared<std::vector<double>>();
  add_grid_options(cmd, *a);
  cmd->add_option("--noise-std", *stds, "noise levels as standard deviations sigma (the official noise_scale)");
  cmd->add_option("--noise-variance", *variances,
                  "noise levels as variances sigma^2 (the paper's caption), "
                  "e.g. 0.001 0.01 0.1");
  cmd->callback([a, stds, variances] {
    run(*a,
        [&](const study::GridOptions& o) { return study::pose_noise_plan(o, study::noise_levels(*stds, *variances)); });
  });
}

}  // namespace

void add_study_grid_commands(CLI::App& study) {
  add_scaling(study);
  add_pose_noise(study);
}

}  // namespace uplvsm::cli
