#include "uplvsm/train/trainer.h"

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/data/subset.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/model/checkpoint_io.h"
#include "uplvsm/model/pretrained_weights.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::atomic<int> g_signal{0};
extern "C" void on_signal(int sig) { g_signal = sig; }

struct SignalScope {
  SignalScope() {
    g_signal = 0;
    old_int = std::signal(SIGINT, on_signal);
    old_term = std::signal(SIGTERM, on_signal);
  }
  ~SignalScope() {
    std::signal(SIGINT, old_int);
    std::signal(SIGTERM, old_term);
  }
  void (*old_int)(int);
  void (*old_term)(int);
};

data::LoaderOptions loader_options(const Config& c, const Communicator* comm) {
  const auto& t = c.training;
  data::LoaderOptions o;
  o.batch_size = t.batch_size;
  o.num_views = static_cast<int>(t.num_views);
  o.num_input_views = static_cast<int>(t.num_input_views);
  o.num_target_views = static_cast<int>(t.num_target_views);
  o.min_frame_dist = static_cast<int>(t.min_frame_dist);
  o.max_frame_dist = static_cast<int>(t.max_frame_dist);
  o.preprocess.image_size = static_cast<int>(c.model.image_size);
  o.preprocess.patch_size = static_cast<int>(c.model.patch_size);
  o.preprocess.square_crop = c.dataset.square_crop;
  o.seed = static_cast<uint64_t>(t.seed);
  o.threads = static_cast<int>(t.loader_threads);
  o.max_scenes = t.max_train_scenes;
  o.pose_noise_variance = t.pose_noise_variance;
  if (comm) {
    o.rank = comm->rank();
    o.world_size = comm->world_size();
  }
  return o;
}

// Keeps metrics.jsonl consistent with the checkpoint we resume from: lines past its step are dropped.
void truncate_metrics(const std::string& path, int64_t step) {
  if (!fs::exists(path)) return;
  std::ifstream in(path);
  std::string kept, line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    try {
      if (json::parse(line).value("step", int64_t{0}) > step) continue;
    } catch (const json::exception&) {
      continue;  // a line cut by a crash
    }
    kept += line + "\n";
  }
  io::write_file_atomic(path, kept.data(), kept.size());
}

void check_same_model(const Config& a, const Config& b, const std::string& source) {
  auto ja = config_to_json(a)["model"], jb = config_to_json(b)["model"];
  if (ja != jb)
    throw std::runtime_error(fmt::format("resume from {}: its model config differs from the given one\n  checkpoint: {}\n  "
                                         "given:      {}",
                                         source, jb.dump(), ja.dump()));
}

// A new run's starting weights; DINOv2 files go into the tokenizer like the official pretrained backbone.
// Returns whether the pose mapper still needs its initial fit (it has one and the file did not carry it).
bool init_from_weights(model::UPLVSMImpl& net, const std::string& path) {
  auto w = model::read_pretrained_weights(path);
  torch::NoGradGuard no_grad;
  model::LoadOptions load;
  if (net.pose_mapper) load.allow_missing_substrings.push_back("pose_mapper.");
  auto report = w.source == model::WeightSource::Uplvsm ? model::load_state_dict(net, w.tensors, path, load)
                                                        : model::load_dinov2_into_uplvsm(net, w.tensors, path);
  spdlog::info("initialised from {} weights: {}", model::to_string(w.source), report.summary(path));
  return net.pose_mapper && !w.tensors.count("pose_mapper.A");
}

// The camera-control stage starts from the least-squares map between real target poses and the latent poses the
// estimator gives them, on calibration batches drawn apart from the training stream (another seed).
void calibrate_pose_mapper(model::UPLVSMImpl& net, const Config& config, const TrainOptions& opt) {
  data::ChunkDataset dataset(opt.data_root, "train");
  auto lo = loader_options(config, nullptr);
  lo.seed += 1000003;
  const int64_t batches = std::max<int64_t>(1, (64 + lo.batch_size - 1) / lo.batch_size);
  torch::NoGradGuard no_grad;
  const bool was_training = net.is_training();
  net.eval();
  std::vector<torch::Tensor> real, latent;
  const int64_t vi = config.training.num_input_views;
  for (int64_t i = 0; i < batches; ++i) {
    auto batch = data::make_training_batch(dataset, lo, i);
    auto dev = [&](const torch::Tensor& t) { return t.to(opt.device); };
    model::Views inputs{dev(batch.input_images(vi)), dev(batch.input_fxfycxcy(vi)), dev(batch.input_c2w(vi))};
    model::Views targets{dev(batch.target_images()), dev(batch.target_fxfycxcy()), dev(batch.target_c2w())};
    auto latents = net.encode_scene(inputs.images, inputs.fxfycxcy);
    latent.push_back(net.estimate_poses(targets.images, latents).reshape({-1, 7}).cpu());
    real.push_back(model::camera_control_poses(inputs.c2w, targets.c2w).reshape({-1, 7}).cpu());
  }
  net.train(was_training);
  const double rms = model::fit_pose_mapper(*net.pose_mapper, torch::cat(real), torch::cat(latent));
  spdlog::info("pose mapper: least-squares fit on {} target views (RMS residual {:.4f})", torch::cat(real).size(0),
               rms);
}

// The perceptual loss the config asks for, when its VGG19 weights were given (null otherwise, with a warning).
PerceptualLoss make_perceptual_loss(const TrainingConfig& tc, const TrainOptions& opt) {
  if (tc.perceptual_loss_weight <= 0) {
    if (!opt.perceptual_weights.empty())
      spdlog::warn("{} not used: training.perceptual_loss_weight is 0", opt.perceptual_weights);
    return nullptr;
  }
  if (opt.perceptual_weights.empty()) {
    spdlog::warn("training.perceptual_loss_weight is {} but no VGG19 weights were given (--vgg19 FILE): training "
                 "with MSE only",
                 tc.perceptual_loss_weight);
    return nullptr;
  }
  auto loss = load_perceptual_loss(opt.perceptual_weights);
  loss->to(opt.device);
  spdlog::info("perceptual loss: VGG19 from {}, weight {}", opt.perceptual_weights, tc.perceptual_loss_weight);
  return loss;
}

// Held-out evaluation on rank 0; a new best PSNR is recorded in the state and its weights kept as best.safetensors.
void run_periodic_eval(const TrainOptions& opt, const Config& config, model::UPLVSM& net, TrainState& state, bool lead,
                       std::ofstream& metrics, const std::string& ckpt_dir) {
  if (lead) {
    net->eval();
    auto result = opt.periodic_eval(net, state.step);
    net->train();
    if (result.contains("psnr") && result.at("psnr").is_number() && result.at("psnr").get<double>() > state.best_eval_psnr) {
      state.best_eval_psnr = result.at("psnr").get<double>();
      result["best"] = save_best_checkpoint(ckpt_dir, config, state, *net);
    }
    metrics << json{{"step", state.step}, {"eval", result}}.dump() << "\n";
    metrics.flush();
  }
  if (opt.comm) opt.comm->barrier();
}

}  // namespace

double psnr_from_mse(double mse) { return -10.0 * std::log10(std::max(mse, 1e-10)); }

TrainResult train(const Config& config, const TrainOptions& opt) {
  const auto& tc = config.training;
  const auto t_start = std::chrono::steady_clock::now();
  Communicator* comm = opt.comm.get();
  const bool lead = !comm || comm->rank() == 0;  // the rank that writes files and shows progress
  fs::create_directories(opt.run_dir);
  const std::string ckpt_dir = (fs::path(opt.run_dir) / "checkpoints").string();
  const std::string metrics_path = (fs::path(opt.run_dir) / "metrics.jsonl").string();
  auto cfg_text = config_to_json(config).dump(2) + "\n";
  if (lead) io::write_file_atomic((fs::path(opt.run_dir) / "config.json").string(), cfg_text.data(), cfg_text.size());

  torch::manual_seed(static_cast<uint64_t>(tc.seed));
  model::UPLVSM net(config.model);
  net->to(opt.device);
  net->train();
  auto optimizer = make_optimizer(*net, tc);
  TrainState state;

  std::string resume_from;
  if (opt.resume == "auto") {
    if (fs::exists(ckpt_dir)) {
      try {
        resume_from = model::resolve_checkpoint(ckpt_dir);
      } catch (const std::runtime_error&) {
      }
    }
  } else if (opt.resume != "none") {
    resume_from = model::resolve_checkpoint(opt.resume);
  }
  if (!resume_from.empty()) {
    auto ckpt = model::read_checkpoint(resume_from);
    check_same_model(config, ckpt.config, resume_from);
    model::load_state_dict(*net, ckpt.model, resume_from);
    restore_optimizer_state(*optimizer, *net, ckpt.optimizer, resume_from);
    state = TrainState::from_json(ckpt.state);
    spdlog::info("resumed from {} at step {}", resume_from, state.step);
  } else if (!opt.init_weights.empty()) {
    if (init_from_weights(*net, opt.init_weights)) calibrate_pose_mapper(*net, config, opt);
  }
  if (lead) truncate_metrics(metrics_path, state.step);
  std::vector<torch::Tensor> params;
  for (const auto& p : net->parameters())
    if (p.requires_grad()) params.push_back(p);
  if (comm) {
    comm->broadcast(net->parameters());  // every rank starts from rank 0's weights
    spdlog::info("data parallel: rank {} of {} ({}), {} scenes per rank and step", comm->rank(), comm->world_size(),
                 comm->backend(), tc.batch_size);
  }

  TrainResult result;
  result.step = state.step;
  if (state.step >= tc.train_steps) {
    spdlog::info("run {} already finished ({} of {} steps)", opt.run_dir, state.step, tc.train_steps);
    return result;
  }
  data::ChunkDataset dataset(opt.data_root, "train");
  if (!tc.subset.empty()) {
    const auto subset = data::read_subset_manifest(tc.subset);
    dataset.keep_only(subset.scenes);
    spdlog::info("subset {} ({}): {} scenes{}", subset.name, tc.subset, dataset.size(),
                 subset.chunks.empty() ? "" : fmt::format(" in {} chunks", subset.chunks.size()));
  }
  const bool reads_cameras = !(config.model.variant == "uplvsm" && model::parse_target_poses(tc.target_poses,
                                                                                               config.model) ==
                                                                        model::TargetPoses::Estimator);
  for (int64_t i = 0; reads_cameras && i < dataset.size(); ++i)
    if (!dataset.poses_known(i))
      throw std::runtime_error(fmt::format("{} training reads ground-truth cameras, but scene {} of {} has none "
                                           "(imported without poses, listed in train/unposed.json)",
                                           config.model.variant, dataset.key(i), opt.data_root));
  if (tc.max_train_scenes > dataset.size())
    throw std::runtime_error(fmt::format("training.max_train_scenes = {}: the train split of {} has only {} scenes",
                                         tc.max_train_scenes, opt.data_root, dataset.size()));
  const int64_t scenes = tc.max_train_scenes > 0 ? tc.max_train_scenes : dataset.size();
  spdlog::info("training {} ({} parameters) on {} scenes of {}{}, steps {} -> {}", config.name, net->parameter_count(),
               scenes, opt.data_root, scenes < dataset.size() ? fmt::format(" (first {} of {})", scenes, dataset.size()) : "",
               state.step, tc.train_steps);
  if (tc.pose_noise_variance > 0)
    spdlog::info("pose noise: N(0, {}) on the (t, q) of every training camera{}", tc.pose_noise_variance,
                 reads_cameras ? "" : " (this UP-LVSM run never reads them)");
  data::TrainingLoader loader(dataset, loader_options(config, comm), state.step);
  PerceptualLoss perceptual = make_perceptual_loss(tc, opt);
  const bool use_bf16 = parse_amp(tc.amp);
  if (use_bf16) spdlog::info("mixed precision: bf16 autocast on {}", opt.device.str());
  const auto target_poses = model::parse_target_poses(tc.target_poses, config.model);
  spdlog::info("{} variant, target poses from {}", config.model.variant, model::to_string(target_poses));
  net->set_grad_checkpoint_every(tc.grad_checkpoint_every);
  if (tc.grad_checkpoint_every > 0)
    spdlog::info("gradient checkpointing: transformer blocks in groups of {}", tc.grad_checkpoint_every);

  SignalScope signals;
  std::ofstream metrics;
  if (lead) metrics.open(metrics_path, std::ios::app);
  const bool show_progress = opt.progress && lead;
  ProgressBar bar("train", tc.train_steps, "step", state.step);
  double loss_ema = -1, mse_ema = -1;
  const int64_t first_step = state.step;
  while (state.step < tc.train_steps) {
    auto t0 = std::chrono::steady_clock::now();
    optimizer->zero_grad();
    double loss_value = 0, mse_value = 0;
    for (int64_t micro = 0; micro < tc.grad_accum_steps; ++micro) {
      auto batch = loader.next();
      auto dev = [&](const torch::Tensor& t) { return t.to(opt.device); };
      auto target = dev(batch.target_images());
      torch::Tensor mse, loss;
      {
        // Forward and losses under autocast as the official step; MSE on fp32 (autocast's policy for losses).
        AutocastGuard amp(opt.device, use_bf16);
        const int64_t vi = tc.num_input_views;
        model::Views inputs{dev(batch.input_images(vi)), dev(batch.input_fxfycxcy(vi)), dev(batch.input_c2w(vi))};
        model::Views targets{target, dev(batch.target_fxfycxcy()), dev(batch.target_c2w())};
        auto out = net->forward(inputs, targets, target_poses);
        mse = torch::mse_loss(out.render.to(torch::kFloat32), target);
        loss = tc.l2_loss_weight * mse;
        if (perceptual) loss = loss + tc.perceptual_loss_weight * perceptual->forward(out.render, target);
      }
      (loss / static_cast<double>(tc.grad_accum_steps)).backward();
      loss_value += loss.item<double>() / static_cast<double>(tc.grad_accum_steps);
      mse_value += mse.item<double>() / static_cast<double>(tc.grad_accum_steps);
    }
    bool stop_signal = g_signal != 0;
    if (comm) {
      // Same decisions on every rank: averaged gradients and losses, and a stop when any rank got a signal.
      average_gradients(*comm, params);
      auto shared = torch::tensor({loss_value, mse_value, stop_signal ? 1.0 : 0.0}, torch::kFloat64);
      comm->allreduce_sum({shared});
      loss_value = shared[0].item<double>() / comm->world_size();
      mse_value = shared[1].item<double>() / comm->world_size();
      stop_signal = shared[2].item<double>() > 0;
    }
    const double lr = tc.lr * lr_lambda(state.scheduler_step, tc.warmup, tc.train_steps);
    double grad_norm = 0;
    bool skipped = false;
    if (!std::isfinite(loss_value)) {
      ++state.skipped_nonfinite;  // official: no optimiser step, no scheduler step
      skipped = true;
    } else {
      for (auto& p : params)
        if (p.grad().defined()) p.grad().nan_to_num_(0.0, 1e-6, -1e-6);
      grad_norm = torch::nn::utils::clip_grad_norm_(params, tc.grad_clip_norm);
      if (grad_norm > tc.grad_clip_norm * tc.allowed_gradnorm_factor) {
        ++state.skipped_gradnorm;  // official: skip the update, still advance the schedule
        skipped = true;
      } else {
        set_learning_rate(*optimizer, lr);
        optimizer->step();
        ++state.param_update_step;
      }
      ++state.scheduler_step;
    }
    ++state.step;
    const double step_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.train_seconds += step_seconds;
    const double psnr = psnr_from_mse(mse_value);
    if (std::isfinite(loss_value)) {
      loss_ema = loss_ema < 0 ? loss_value : 0.95 * loss_ema + 0.05 * loss_value;
      mse_ema = mse_ema < 0 ? mse_value : 0.95 * mse_ema + 0.05 * mse_value;
    }
    result.last_loss = loss_value;
    result.last_psnr = psnr;
    if (lead && (state.step % tc.log_every == 0 || state.step == tc.train_steps || state.step == first_step + 1)) {
      metrics << json{{"step", state.step}, {"loss", loss_value}, {"mse", mse_value}, {"psnr", psnr}, {"lr", lr}, {"grad_norm", grad_norm},
                      {"skipped", skipped}, {"step_seconds", step_seconds}, {"data_wait_seconds", loader.wait_seconds()},
                      {"chunk_reads", dataset.chunk_reads()}, {"train_seconds", state.train_seconds}}
                     .dump()
              << "\n";
      metrics.flush();
    }
    if (show_progress)
      bar.update(state.step, {{"loss", fmt::format("{:.4f}", loss_ema)},
                              {"psnr", fmt::format("{:.2f}", psnr_from_mse(mse_ema))},
                              {"lr", fmt::format("{:.2e}", lr)}});
    const bool stop_now = stop_signal || (opt.stop_after_steps > 0 && state.step - first_step >= opt.stop_after_steps);
    // Evaluation first, so the checkpoint of this step carries its best-so-far record.
    const bool eval_now = opt.periodic_eval && tc.eval_every > 0 &&
                          (state.step % tc.eval_every == 0 || state.step == tc.train_steps);
    if (eval_now) run_periodic_eval(opt, config, net, state, lead, metrics, ckpt_dir);
    if (lead && (state.step % tc.checkpoint_every == 0 || state.step == tc.train_steps || stop_now)) {
      result.last_checkpoint = save_training_checkpoint(ckpt_dir, config, state, *net, *optimizer, tc.keep_checkpoints);
    }
    if (stop_now) {
      result.interrupted = stop_signal;
      if (result.interrupted) spdlog::warn("signal {}: checkpoint written to {}, exiting", int(g_signal), result.last_checkpoint);
      break;
    }
  }
  if (show_progress) bar.finish();
  spdlog::info("data: {:.1f} s waiting on the loader, {} chunk files read", loader.wait_seconds(), dataset.chunk_reads());
  if (comm) {
    check_parameters_in_sync(*comm, net->parameters());
    comm->barrier();  // rank 0's last checkpoint is on disk before any rank returns
    spdlog::info("rank {}: parameters identical on all {} ranks", comm->rank(), comm->world_size());
  }
  result.step = state.step;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  if (state.skipped_nonfinite + state.skipped_gradnorm > 0)
    spdlog::warn("skipped updates: {} non-finite losses, {} gradient norms above {} x clip", state.skipped_nonfinite,
                 state.skipped_gradnorm, tc.allowed_gradnorm_factor);
  return result;
}

}  // namespace uplvsm::train
