// `uplvsm eval`: scores a checkpoint on an evaluation index with the paper's unposed protocol, beside the two
// baselines; writes metrics.json, per-scene/per-view CSV and image grids.
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/model/checkpoint_io.h"

namespace uplvsm::cli {

void add_eval_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "eval", "Evaluate a checkpoint on held-out scenes (unposed protocol: the estimator sees each target image), "
              "with the copy-nearest-input and mean-colour baselines; per scene mean, then mean over scenes, and per "
              "overlap bucket when the index has overlaps.");
  struct Args {
    CommonOptions common;
    ModelSource model;
  std::string data, split = "test", index, out;
    int64_t max_scenes = 0, batch = 4, visualise = 8;
  };
  auto a = std::make_shared<Args>();
  add_common_options(cmd, a->common);
  add_model_options(cmd, a->model);
  cmd->add_option("--data", a->data, "dataset root (pixelSplat chunks)")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a->split, "dataset split")->capture_default_str();
  cmd->add_option("--index", a->index, "evaluation index (pixelSplat / NoPoSplat / official split JSON); default "
                                       "<data>/evaluation_index.json");
  cmd->add_option("--max-scenes", a->max_scenes, "evaluate at most this many scenes (0: all)")->capture_default_str();
  cmd->add_option("--batch", a->batch, "scenes per forward pass")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--visualise", a->visualise, "PNG grids for this many scenes")->capture_default_str();
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] {
    apply_common_options(a->common);
    Config config;
    auto device = parse_device(a->common.device);
    auto net = load_model(a->model, device, &config);
    data::ChunkDataset dataset(a->data, a->split);
    data::PreprocessOptions prep{static_cast<int>(config.model.image_size), static_cast<int>(config.model.patch_size),
                                 config.dataset.square_crop};
    eval::EvalOptions opt;
    opt.index_path = a->index;
    opt.max_scenes = a->max_scenes;
    opt.batch_size = a->batch;
    opt.device = device;
    opt.num_visualised = a->visualise;
    opt.out_dir = a->out;
    opt.extra = {{"checkpoint", model::resolve_checkpoint(a->model.checkpoint)}, {"data", a->data}, {"split", a->split},
                 {"config", config.name}};
    auto summary = eval::evaluate(net, dataset, prep, opt);
    const auto& t = summary.table;
    std::cout << fmt::format(
        "evaluated {} scenes in {:.1f} s -> {}/metrics.json\n  UP-LVSM        PSNR {:6.2f}  SSIM {:.4f}\n"
        "  copy nearest   PSNR {:6.2f}  SSIM {:.4f}\n  mean colour    PSNR {:6.2f}  SSIM {:.4f}\n",
        summary.scenes, summary.seconds, a->out, t.at("model").at("psnr"), t.at("model").at("ssim"),
        t.at("copy_nearest").at("psnr"), t.at("copy_nearest").at("ssim"), t.at("mean_colour").at("psnr"),
        t.at("mean_colour").at("ssim"));
  });
}

}  // namespace uplvsm::cli
