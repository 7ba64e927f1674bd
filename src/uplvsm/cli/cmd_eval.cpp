// `uplvsm eval`: scores a checkpoint on an evaluation index with the paper's unposed protocol, beside the two
// baselines (LPIPS too when its weight files are given); writes metrics.json, per-scene/per-view CSV and image grids.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/eval/camera_jitter.h"
#include "uplvsm/eval/eval_pose_noise.h"
#include "uplvsm/eval/evaluator.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/study/camera_paths.h"
#include "uplvsm/train/distributed.h"

namespace uplvsm::cli {

namespace {

struct EvalArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource scenes;
  std::string out, lpips_net = "vgg", lpips_backbone, lpips_lin;
  Amp amp = Amp::None;
  TargetPoses target_poses = TargetPoses::Auto;
  int64_t max_scenes = 0, batch = 4, visualise = 8;
  eval::PoseRefinement refinement;
  double pose_noise_std = 0;
  uint64_t seed = 0;
  bool jitter = false;
  std::string trajectory;
  int64_t trajectory_frames = 96;
};

void add_eval_options(CLI::App* cmd, EvalArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
  add_mapper_option(cmd, a.model);
  add_scene_source_options(cmd, a.scenes, "dataset root (pixelSplat chunks)",
                           "evaluation index (pixelSplat / NoPoSplat / official split JSON); default "
                           "<data>/evaluation_index.json");
  cmd->get_option("--data")->required();
  cmd->add_option("--max-scenes", a.max_scenes, "evaluate at most this many scenes (0: all)")->capture_default_str();
  cmd->add_option("--batch", a.batch, "scenes per forward pass")->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_option("--visualise", a.visualise, "PNG grids for this many scenes")->capture_default_str();
  cmd->add_option("--out", a.out, "output directory")->required();
  add_amp_option(cmd, a.amp, "model forward precision: none (fp32) or bf16 autocast (metrics stay fp32)");
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
  cmd->add_flag("--jitter", a.jitter,
                "also render a smooth path along each scene's real cameras (camera control: --mapper, the "
                "checkpoint's mapper or a posed model) and report the jitter, how much the rendered picture's motion "
                "changes from one render to the next in pixels per frame² (jitter.json)");
  cmd->add_option("--trajectory", a.trajectory,
                  "built-in rooms: also score camera control along this path past the inputs (orbit, spiral, "
                  "dolly or a camera-path file in baseline units) against the ray-traced truth, as `study "
                  "camera-paths` does: PSNR/SSIM inside and beyond the inputs' span, wobble (<out>/trajectory/)")
      ->check(CLI::IsMember({"orbit", "spiral", "dolly"}) | CLI::ExistingFile);
  cmd->add_option("--trajectory-frames", a.trajectory_frames, "poses of a --trajectory preset")
      ->check(CLI::Range(3, 1000))
      ->capture_default_str();
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

// The evaluator's options from the command line and the checkpoint's config; with a communicator, this process
// scores its shard of the scenes and the results are gathered.
eval::EvalOptions eval_options(const EvalArgs& a, const Config& config, model::NovelViewModel& net,
                               torch::Device device, const std::shared_ptr<train::Communicator>& comm) {
  eval::EvalOptions opt;
  opt.index_path = a.scenes.index;
  opt.max_scenes = a.max_scenes;
  opt.batch_size = a.batch;
  opt.device = device;
  opt.num_visualised = a.visualise;
  opt.out_dir = a.out;
  opt.pose_refinement = a.refinement;
  opt.pose_noise_std = a.pose_noise_std;
  opt.pose_noise_seed = a.seed;
  opt.bf16 = a.amp == Amp::Bf16;
  // auto: as trained (a UP-LVSM trained from dataset cameras has an untrained estimator).
  // auto with --mapper: the mapper given for it.
  auto choice = a.target_poses;
  if (choice == TargetPoses::Auto) choice = a.model.mapper.empty() ? config.training.target_poses : TargetPoses::Mapper;
  opt.target_poses = model::resolve_target_poses(choice, *net);
  if (comm) {
    opt.shard_rank = comm->rank();
    opt.shard_count = comm->world_size();
    opt.gather = [comm](const std::string& mine) { return comm->all_gather(mine); };
  }
  if (!a.lpips_backbone.empty()) {
    opt.lpips = eval::load_lpips(eval::parse_lpips_net(a.lpips_net), a.lpips_backbone, a.lpips_lin);
    opt.lpips->to(device);
  }
  opt.extra = {{"checkpoint", io::resolve_checkpoint(a.model.checkpoint)},
               {"mapper", a.model.mapper},
               {"data", a.scenes.data},
               {"split", a.scenes.split},
               {"config", config.name},
               {"variant", to_string(config.model.variant)},
               {"target_poses", uplvsm::to_string(opt.target_poses)}};
  if (a.refinement.steps > 0) opt.extra["pose_refinement"] = {{"steps", a.refinement.steps}, {"lr", a.refinement.lr}};
  return opt;
}

void print_eval_summary(const EvalArgs& a, const Config& config, const eval::EvalOptions& opt,
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
void report_jitter(const EvalArgs& a, model::NovelViewModel& net, const data::ChunkDataset& dataset,
                   const data::PreprocessOptions& prep, const eval::EvalOptions& eval_opt) {
  eval::JitterOptions opt;
  opt.index_path = a.scenes.index;
  opt.max_scenes = a.max_scenes;
  opt.device = eval_opt.device;
  opt.bf16 = eval_opt.bf16;
  auto j = eval::measure_jitter(net, dataset, prep, opt);
  auto out = j.to_json();
  out["mapper"] = a.model.mapper;
  out["checkpoint"] = a.model.checkpoint;
  std::filesystem::create_directories(a.out);
  const auto text = out.dump(2) + "\n";
  io::write_file_atomic((std::filesystem::path(a.out) / "jitter.json").string(), text.data(), text.size());
  std::cout << fmt::format(
      "  jitter along {} smooth camera paths ({} renders): {:.3f} px/frame² (how much the rendered picture's motion "
      "changes from one render to the next; its speed: {:.2f} px/frame) -> {}/jitter.json\n",
      j.scenes, j.renders, j.jitter, j.speed, a.out);
}

// Camera control along a user's path on the same rooms (study/camera_paths.h), written under <out>/trajectory.
void report_trajectory(const EvalArgs& a, const Config& config, model::NovelViewModel& net,
                       const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                       const eval::EvalOptions& eval_opt) {
  study::CameraPathsOptions opt;
  opt.trajectory = a.trajectory;
  opt.frames = a.trajectory_frames;
  opt.index_path = a.scenes.index;
  opt.max_scenes = a.max_scenes;
  opt.room = data::room_scene_options(config.dataset);  // the rooms the checkpoint was trained on
  opt.device = eval_opt.device;
  opt.bf16 = eval_opt.bf16;
  const auto report = study::run_camera_paths(net, dataset, prep, opt);
  const auto out = (std::filesystem::path(a.out) / "trajectory").string();
  study::write_camera_paths(report, out);
  for (const auto& m : report.methods)
    std::cout << fmt::format(
        "  {} path, {}: PSNR {:.2f} dB inside the inputs' span, {:.2f} beyond; wobble {:.3f} "
        "px/frame² -> {}/camera_paths.json\n",
        a.trajectory, m.method, m.psnr_inside, m.psnr_beyond, m.wobble, out);
}

void run_eval(const EvalArgs& a) {
  eval::check_pose_noise_std(a.pose_noise_std);  // before the model is loaded
  apply_common_options(a.common);
  Config config;
  // torchrun / SLURM variables make this process one shard of a multi-process evaluation (results merged).
  const auto env = train::distributed_env_from_environment();
  auto device = train::rank_device(parse_device(a.common.device), env);
  std::shared_ptr<train::Communicator> comm;
  if (env.distributed()) comm = std::make_shared<train::Communicator>(env, device);
  auto net = load_model_from_source(a.model, device, &config);
  data::ChunkDataset dataset(a.scenes.data, a.scenes.split);
  const auto prep = data::preprocess_options(config);
  const auto opt = eval_options(a, config, net, device, comm);
  auto summary = eval::evaluate(net, dataset, prep, opt);
  if (comm && comm->rank() != 0) return;  // rank 0 reports for all shards
  print_eval_summary(a, config, opt, summary);
  if (a.jitter) report_jitter(a, net, dataset, prep, opt);
  if (!a.trajectory.empty()) report_trajectory(a, config, net, dataset, prep, opt);
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
