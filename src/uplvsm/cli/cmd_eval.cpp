// `uplvsm eval`: scores a checkpoint on an evaluation index with the paper's unposed protocol, beside the two
// baselines (LPIPS too when its weight files are given); writes metrics.json, per-scene/per-view CSV and image grids.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/eval/eval_pose_noise.h"
#include "uplvsm/eval/evaluation_run.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/camera_paths.h"
#include "uplvsm/train/distributed.h"

namespace uplvsm::cli {

namespace {

struct EvalArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource scenes;
  eval::EvalRequest request;
  Amp amp = Amp::None;
  bool jitter = false;
  // The request with the model source, scenes and precision in.
  eval::EvalRequest full_request() const {
    auto r = request;
    r.checkpoint = model.checkpoint, r.mapper = model.mapper;
    r.data = scenes.data, r.split = scenes.split, r.index = scenes.index;
    r.bf16 = amp == Amp::Bf16;
    return r;
  }
  std::string trajectory, room_config;
  int64_t trajectory_frames = 96;
};

// Camera control along a path past the inputs, scored against the built-in rooms' ray-traced truth.
void add_trajectory_options(CLI::App* cmd, EvalArgs& e) {
  cmd->add_option("--trajectory", e.trajectory,
                  "built-in rooms: also score camera control along this path past the inputs (orbit, spiral, "
                  "dolly or a camera-path file in baseline units) against the ray-traced truth, as `study "
                  "camera-paths` does: PSNR/SSIM inside and beyond the inputs' span, wobble (<out>/trajectory/)")
      ->check(CLI::IsMember({"orbit", "spiral", "dolly"}) | CLI::ExistingFile);
  cmd->add_option("--trajectory-frames", e.trajectory_frames, "poses of a --trajectory preset")
      ->check(CLI::Range(3, 1000))
      ->capture_default_str();
  cmd->add_option("--room-config", e.room_config,
                  "--trajectory: the config the rooms were made with (default: the checkpoint's dataset section)")
      ->check(CLI::ExistingFile);
}

void add_eval_options(CLI::App* cmd, EvalArgs& e) {
  add_common_options(cmd, e.common);
  add_model_options(cmd, e.model);
  add_mapper_option(cmd, e.model);
  auto& a = e.request;
  add_scene_source_options(cmd, e.scenes, "dataset root (pixelSplat chunks)",
                           "evaluation index (pixelSplat / NoPoSplat / official split JSON); default "
                           "<data>/evaluation_index.json");
  cmd->get_option("--data")->required();
  cmd->add_option("--max-scenes", a.max_scenes, "evaluate at most this many scenes (0: all)")->capture_default_str();
  cmd->add_option("--batch", a.batch, "scenes per forward pass")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--visualise", a.visualise, "PNG grids for this many scenes")->capture_default_str();
  cmd->add_option("--out", a.out, "output directory")->required();
  add_amp_option(cmd, e.amp, "model forward precision: none (fp32) or bf16 autocast (metrics stay fp32)");
  add_target_poses_option(cmd, a.target_poses,
                          "where target cameras come from: auto (the protocol the model was trained with, its "
                          "training.target_poses: the estimator for UP-LVSM, dataset cameras for ptlvsm/lvsm, the "
                          "mapper after the camera-control stage), estimator, mapper (dataset cameras through the "
                          "camera-control mapper) or dataset");
  cmd->add_option("--refine-poses", a.refinement.steps,
                  "UP-LVSM, estimator protocol: refine each target's latent pose by this many Adam steps on its "
                  "render's error against the target, the model frozen (the target-pose alignment of pose-free "
                  "evaluations; 0: the paper's protocol, the estimator's poses as they are)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--refine-lr", a.refinement.lr, "learning rate of --refine-poses")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--pose-noise-std", a.pose_noise_std,
                  "score as the official code does with unposed.noise_scale = S: N(0, S^2) on the (t, q) encodings "
                  "of the test cameras the model reads (LVSM's and PT-LVSM's inputs and targets; UP-LVSM's only with "
                  "mapper or dataset target poses), in the scene frame, inputs and targets drawn apart; 0: clean")
      ->capture_default_str();
  cmd->add_option("--seed", a.seed, "seed of --pose-noise-std (each scene draws from this seed and its key)")
      ->capture_default_str();
  cmd->add_flag("--jitter", e.jitter,
                "also render a smooth path along each scene's real cameras (camera control: --mapper, the "
                "checkpoint's mapper or a posed model) and report the jitter, how much the rendered picture's motion "
                "changes from one render to the next in pixels per frame² (jitter.json)");
  add_trajectory_options(cmd, e);
  cmd->add_option("--lpips-net", a.lpips_net, "LPIPS backbone: vgg (the papers' choice) or alex")
      ->check(CLI::IsMember({"vgg", "alex"}))
      ->capture_default_str();
  auto* backbone = cmd->add_option("--lpips-backbone", a.lpips_backbone,
                                   "torchvision-format VGG16 / AlexNet weights (features.N.*; .pth, .pt or "
                                   "safetensors); without it LPIPS is reported as unavailable")
                       ->check(CLI::ExistingFile);
  cmd->add_option("--lpips-lin", a.lpips_lin,
                  "the official lpips v0.1 lin weights (lpips/weights/v0.1/<net>.pth) "
                  "or a safetensors copy")
      ->check(CLI::ExistingFile)
      ->needs(backbone);
  backbone->needs("--lpips-lin");
}

void print_eval_summary(const eval::EvalRequest& a, const Config& config, const eval::EvalOptions& opt,
                        const eval::EvalSummary& summary) {
  auto line = [&](const std::string& name, const eval::Scores& r) {
    const auto lpips = opt.lpips ? fmt::format("{:.4f}", r.lpips) : std::string("unavailable");
    return fmt::format("  {:<20} PSNR {:6.2f}  SSIM {:.4f}  edges {:.3f}  LPIPS {}\n", name, r.psnr, r.ssim,
                       r.grad_ratio, lpips);
  };
  std::cout << fmt::format("evaluated {} scenes in {:.1f} s -> {}/metrics.json\n", summary.scenes, summary.seconds,
                           a.out)
            << line(to_string(config.model.variant) + " (" + uplvsm::to_string(opt.target_poses) +
                        (a.refinement.steps > 0 ? ", refined" : "") + ")",
                    summary.scores.model)
            << line("copy nearest", summary.scores.copy_nearest) << line("mean colour", summary.scores.mean_colour);
  if (!opt.lpips) std::cout << "  (LPIPS unavailable: pass --lpips-backbone and --lpips-lin to score it)\n";
  const auto& noise = summary.pose_noise;
  std::cout << (opt.pose_noise_std > 0 ? fmt::format("  pose noise sd {} (seed {}): {}\n", opt.pose_noise_std, a.seed,
                                                     noise.at("cameras").get<std::string>())
                                       : std::string("  pose noise: none, clean test cameras (--pose-noise-std)\n"));
}

// Jitter along the same scenes' camera paths, written beside metrics.json.
void report_jitter(const eval::EvalRequest& r, model::NovelViewModel& net, const data::ChunkDataset& dataset,
                   const data::PreprocessOptions& prep, torch::Device device) {
  const auto j = eval::write_jitter(r, net, dataset, prep, device);
  std::cout << fmt::format(
      "  jitter along {} smooth camera paths ({} renders): {:.3f} px/frame² (how much the rendered picture's motion "
      "changes from one render to the next; its speed: {:.2f} px/frame) -> {}/jitter.json\n",
      j.scenes, j.renders, j.jitter, j.speed, r.out);
}

// Camera control along a user's path on the same rooms (study/camera_paths.h), written under <out>/trajectory.
void report_trajectory(const EvalArgs& a, const eval::EvalRequest& r, const Config& config, model::NovelViewModel& net,
                       const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                       const eval::EvalOptions& eval_opt) {
  study::CameraPathsOptions opt;
  opt.trajectory = a.trajectory;
  opt.frames = a.trajectory_frames;
  opt.index_path = a.scenes.index;
  opt.max_scenes = r.max_scenes;
  // By default the rooms the checkpoint was trained on.
  opt.room = data::room_scene_options(a.room_config.empty() ? config.dataset : load_config(a.room_config).dataset);
  opt.device = eval_opt.device;
  opt.bf16 = eval_opt.bf16;
  const auto report = study::run_camera_paths(net, dataset, prep, opt);
  const auto out = (std::filesystem::path(r.out) / "trajectory").string();
  study::write_camera_paths(report, out);
  for (const auto& m : report.methods)
    std::cout << fmt::format(
        "  {} path, {}: PSNR {:.2f} dB inside the inputs' span, {:.2f} beyond; wobble {:.3f} "
        "px/frame² -> {}/camera_paths.json\n",
        a.trajectory, m.method, m.psnr_inside, m.psnr_beyond, m.wobble, out);
}

void run_eval(const EvalArgs& a) {
  const auto request = a.full_request();
  eval::check_pose_noise_std(request.pose_noise_std);  // before the model is loaded
  apply_common_options(a.common);
  Config config;
  // torchrun / SLURM variables make this process one shard of a multi-process evaluation (results merged).
  const auto env = train::distributed_env_from_environment();
  auto device = train::rank_device(parse_device(a.common.device), env);
  std::shared_ptr<train::Communicator> comm;
  if (env.distributed()) comm = std::make_shared<train::Communicator>(env, device);
  auto net = load_model_from_source(a.model, device, &config);
  if (!a.trajectory.empty() && !net->has_camera_control())  // before the evaluation, not after it
    throw std::runtime_error("eval --trajectory: " + a.model.checkpoint +
                             " has no camera mapper: give --mapper FILE (fit one with `uplvsm fit-mapper`, minutes) "
                             "or a model fine-tuned with `uplvsm train --stage mapper`");
  data::ChunkDataset dataset(a.scenes.data, a.scenes.split);
  const auto prep = data::preprocess_options(config);
  auto opt = eval::evaluation_options(request, config, net, device);
  if (comm) {
    opt.shard_rank = comm->rank();
    opt.shard_count = comm->world_size();
    opt.gather = [comm](const std::string& mine) { return comm->all_gather(mine); };
  }
  auto summary = eval::evaluate(net, dataset, prep, opt);
  if (comm && comm->rank() != 0) return;  // rank 0 reports for all shards
  print_eval_summary(request, config, opt, summary);
  if (a.jitter) report_jitter(request, net, dataset, prep, device);
  if (!a.trajectory.empty()) report_trajectory(a, request, config, net, dataset, prep, opt);
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "eval",
      "Evaluate a checkpoint on held-out scenes (unposed protocol: the estimator sees each target image), "
      "with the copy-nearest-input and mean-colour baselines; per scene mean, then mean over scenes, and per "
      "overlap bucket when the index has overlaps. Multi-process: launch one process per device with "
      "torchrun's variables (RANK, WORLD_SIZE, ...); the scenes are sharded and rank 0 writes the merged "
      "results.");
  auto a = std::make_shared<EvalArgs>();
  add_eval_options(cmd, *a);
  cmd->callback([a] { run_eval(*a); });
}

}  // namespace uplvsm::cli
