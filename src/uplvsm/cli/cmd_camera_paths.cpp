// `uplvsm study camera-paths`: camera control scored against ground truth along paths that leave the inputs' range,
// on the built-in rooms (study/camera_paths.h).
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/study/camera_paths.h"
#include "uplvsm/study/camera_paths_summary.h"

namespace uplvsm::cli {

namespace {

struct CameraPathsArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource scenes;
  std::string out, room_config;
  Amp amp = Amp::None;
  bool no_estimator = false;
  study::CameraPathsOptions opt;
};

void run_camera_paths(CameraPathsArgs& a) {
  apply_common_options(a.common);
  Config config;
  a.opt.device = parse_device(a.common.device);
  a.opt.bf16 = a.amp == Amp::Bf16;
  a.opt.estimator = !a.no_estimator;
  auto net = load_model_from_source(a.model, a.opt.device, &config);
  // The rooms of the config the dataset was made with (make-dataset --config), by default the checkpoint's own (the
  // demo models carry the dataset section they were trained on).
  a.opt.room = data::room_scene_options(a.room_config.empty() ? config.dataset : load_config(a.room_config).dataset);
  a.opt.index_path = a.scenes.index;
  data::ChunkDataset dataset(a.scenes.data, a.scenes.split);
  auto report = study::run_camera_paths(net, dataset, data::preprocess_options(config), a.opt);
  study::write_camera_paths(report, a.out);
  std::cout << fmt::format("{} scenes, {} path frames inside the inputs' span and {} beyond ({} path, {} frames):\n",
                           report.scenes, report.frames_inside, report.frames_beyond, a.opt.trajectory, a.opt.frames);
  for (const auto& m : report.methods)
    std::cout << fmt::format(
        "  {:<28} PSNR inside {:.2f} dB, beyond {:.2f} dB; SSIM inside {:.4f}, beyond {:.4f}; wobble {:.3f} "
        "px/frame²\n",
        m.method, m.psnr_inside, m.psnr_beyond, m.ssim_inside, m.ssim_beyond, m.wobble);
  std::cout << "-> " << a.out << "/camera_paths.json, camera_paths.csv, camera_paths_scenes.csv\n";
}

void run_summary(const std::vector<std::string>& run_args, const std::string& out) {
  std::vector<study::CameraPathsRun> runs;
  for (const auto& r : run_args) runs.push_back(study::parse_camera_paths_run(r));
  const auto summary = study::summarise_camera_paths(runs);
  study::write_camera_paths_summary(summary, out);
  for (const auto& s : summary.stats)
    std::cout << fmt::format("  {:<11} {}{}{}: {:.3f} [{:.3f}, {:.3f}] ({} scenes)\n", s.metric, s.a,
                             s.b.empty() ? "" : " - ", s.b, s.interval.estimate, s.interval.lo, s.interval.hi,
                             s.interval.scenes);
  std::cout << "-> " << out << "/summary.json, differences.csv, psnr_position.png\n";
}

void add_summary_command(CLI::App& study) {
  auto runs = std::make_shared<std::vector<std::string>>();
  auto out = std::make_shared<std::string>();
  auto* cmd = study.add_subcommand(
      "camera-paths-summary",
      "Several camera-paths runs on the same rooms compared scene by scene: each method's mean and every pair's "
      "difference (wobble, PSNR inside and beyond the inputs' span) with a paired 95 % bootstrap interval over the "
      "scenes, and PSNR against the position along the inputs' baseline (psnr_position.png)");
  cmd->add_option("runs", *runs, "camera-paths output folders, LABEL=DIR or DIR")->required();
  cmd->add_option("--out", *out, "output directory")->required();
  cmd->callback([runs, out] { run_summary(*runs, *out); });
}

}  // namespace

void add_camera_paths_command(CLI::App& study) {
  auto a = std::make_shared<CameraPathsArgs>();
  auto* cmd = study.add_subcommand(
      "camera-paths",
      "Camera control against ground truth on the built-in rooms: a preset path (by default a dolly 1.5 baselines "
      "forward and back, past both inputs) around each held-out scene's first input view, the truth ray-traced at "
      "every frame; PSNR/SSIM inside the inputs' span and beyond it, and the wobble relative to the truth's motion, "
      "for the model's camera control and (UP-LVSM) the estimator reading the true frame");
  add_common_options(cmd, a->common);
  add_model_options(cmd, a->model);
  add_mapper_option(cmd, a->model);
  add_scene_source_options(cmd, a->scenes, "a built-in rooms dataset (make-dataset)",
                           "evaluation index (default <data>/evaluation_index.json)");
  cmd->get_option("--data")->required();
  cmd->add_option("--room-config", a->room_config,
                  "the config the dataset was made with (make-dataset --config); default: the checkpoint's")
      ->check(CLI::ExistingFile);
  cmd->add_option("--trajectory", a->opt.trajectory, "path preset (orbit, spiral, dolly) or a camera-path file")
      ->check(CLI::IsMember({"orbit", "spiral", "dolly"}) | CLI::ExistingFile)
      ->capture_default_str();
  cmd->add_option("--frames", a->opt.frames, "poses per path")->check(CLI::Range(3, 1000))->capture_default_str();
  cmd->add_option("--radius", a->opt.preset.radius, "dolly travel / spiral radius, baselines")->capture_default_str();
  cmd->add_option("--arc", a->opt.preset.arc_degrees, "orbit swing, degrees")->capture_default_str();
  cmd->add_option("--focus", a->opt.preset.focus_distance, "orbit / spiral focus, baselines in front")
      ->capture_default_str();
  cmd->add_flag("--no-estimator", a->no_estimator,
                "leave out the estimator reading the true frame (it does not depend on the mapper)");
  cmd->add_option("--max-scenes", a->opt.max_scenes, "at most this many scenes (0: all)")->capture_default_str();
  add_amp_option(cmd, a->amp, "model forward precision: none (fp32) or bf16 autocast");
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] { run_camera_paths(*a); });
  add_summary_command(study);
}

}  // namespace uplvsm::cli
