#include "uplvsm/train/trainer.h"

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/core/psnr.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/data/subset.h"
#include "uplvsm/data/view_sampler.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/checkpoint.h"
#include "uplvsm/train/global_batch.h"
#include "uplvsm/train/memory_estimate.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/perceptual_loss.h"
#include "uplvsm/train/run_plan.h"
#include "uplvsm/train/run_start.h"
#include "uplvsm/train/tokenizer_start.h"
#include "uplvsm/train/train_step.h"

namespace uplvsm::train {

namespace fs = std::filesystem;
using nlohmann::json;

data::LoaderOptions loader_options(const Config& c, const data::ChunkDataset& dataset, const Communicator* comm) {
  const auto& t = c.training;
  data::LoaderOptions o;
  o.ordered_views = data::uses_ordered_views(t.view_sampler, dataset.info());
  o.batch_size = t.batch_size;
  o.num_views = static_cast<int>(t.num_views);
  o.num_input_views = static_cast<int>(t.num_input_views);
  o.num_target_views = static_cast<int>(t.num_target_views);
  o.min_frame_dist = static_cast<int>(t.min_frame_dist);
  o.max_frame_dist = static_cast<int>(t.max_frame_dist);
  o.frame_dist_curriculum_steps = t.frame_dist_curriculum_steps;
  o.preprocess.image_size = static_cast<int>(c.model.image_size);
  o.preprocess.patch_size = static_cast<int>(c.model.patch_size);
  o.preprocess.square_crop = c.dataset.square_crop;
  o.seed = static_cast<uint64_t>(t.seed);
  o.threads = static_cast<int>(t.loader_threads);
  o.max_scenes = t.max_train_scenes;
  o.chunks_per_shuffle = t.chunks_per_shuffle;
  o.pose_noise_std = t.pose_noise_std;
  if (comm) {
    o.rank = comm->rank();
    o.world_size = comm->world_size();
  }
  o.micro_batches_per_step = plan_batch(t, o.world_size, c.name).accumulation;
  return o;
}

StepContext step_context(model::NovelViewModelImpl& net, torch::optim::Optimizer& optimizer, const Config& config,
                         const TrainOptions& opt) {
  const auto& tc = config.training;
  StepContext ctx;
  ctx.net = &net;
  ctx.optimizer = &optimizer;
  ctx.params = trainable_parameters(net);
  ctx.training = tc;
  ctx.target_poses = model::resolve_target_poses(tc.target_poses, net);
  ctx.perceptual =
      perceptual_loss_for(tc.perceptual_loss_weight, opt.perceptual_weights, opt.device, opt.perceptual_input);
  ctx.bf16 = use_bf16_autocast(tc.amp == Amp::Bf16, opt.device);
  ctx.comm = opt.comm.get();
  if (set_cuda_tf32(opt.device, tc.tf32)) spdlog::info("TF32 matmuls and convolutions: {}", tc.tf32 ? "on" : "off");
  spdlog::info("{} ({} variant), target poses from {}", net.name(), to_string(config.model.variant),
               uplvsm::to_string(ctx.target_poses));
  net.set_grad_checkpoint_every(tc.grad_checkpoint_every);
  if (tc.grad_checkpoint_every > 0)
    spdlog::info("gradient checkpointing: transformer blocks in groups of {}", tc.grad_checkpoint_every);
  return ctx;
}

MicroBatch micro_batch(const data::TrainingBatch& batch, int64_t input_views, torch::Device device) {
  auto dev = [&](const torch::Tensor& t) { return t.to(device); };
  // The loader's cameras are in the scene frame of all the sample's views (with their pose noise, if any).
  return {
      {dev(batch.input_images(input_views)), dev(batch.input_fxfycxcy(input_views)), dev(batch.input_c2w(input_views)),
       model::CameraFrame::Scene},
      {dev(batch.target_images()), dev(batch.target_fxfycxcy()), dev(batch.target_c2w()), model::CameraFrame::Scene}};
}

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

// Held-out evaluation on rank 0, into metrics.jsonl: a monitor that selects no weights (checkpoint.h).
void run_periodic_eval(const TrainOptions& opt, model::NovelViewModel& net, const TrainState& state, bool lead,
                       std::ofstream& metrics) {
  if (lead) {
    json result;
    {
      EvalModeGuard mode(*net);
      result = opt.periodic_eval(net, state.step);
    }
    metrics << json{{"step", state.step}, {"eval", result}}.dump() << "\n";
    metrics.flush();
  }
  if (opt.comm) opt.comm->barrier();
}

// Refuses, before anything is allocated, a config whose training state and activations (a lower bound) exceed the
// memory the device has free: one line with both numbers instead of LibTorch's failed allocation.
void check_memory_fits(const Config& config, torch::Device device) {
  const auto need = train::training_memory(config);
  const auto available = available_memory(device);
  if (!available || need.total() <= static_cast<double>(available->bytes)) return;
  throw std::runtime_error(fmt::format(
      "config {}: training needs at least {} ({} parameters: {} for weights, gradients and AdamW state, {} of "
      "activations for a batch of {}), but only {} is available ({}); reduce model dimensions or training.batch_size",
      config.name, format_bytes(need.total()), need.parameters, format_bytes(need.state_bytes),
      format_bytes(need.activation_bytes), config.training.batch_size, format_bytes(double(available->bytes)),
      available->source));
}

// The run directory's files; the lead rank writes config.json.
struct RunFiles {
  std::string checkpoint_dir, metrics;
};

RunFiles prepare_run_dir(const Config& config, const TrainOptions& opt, bool lead) {
  fs::create_directories(opt.run_dir);
  auto cfg_text = config_to_json(config).dump(2) + "\n";
  if (lead) io::write_file_atomic((fs::path(opt.run_dir) / "config.json").string(), cfg_text.data(), cfg_text.size());
  return {(fs::path(opt.run_dir) / "checkpoints").string(), (fs::path(opt.run_dir) / "metrics.jsonl").string()};
}

// The official whole-split order over pixelSplat chunks larger than the chunk cache reads about one chunk (~100 MB
// on RealEstate10K) per sample: said at the start, with the two ways out (docs/training.md has the figures).
void warn_if_shuffling_rereads_chunks(const data::ChunkDataset& dataset, const TrainingConfig& tc) {
  if (tc.chunks_per_shuffle != 0 || dataset.layout() != data::ChunkDataset::Layout::Chunks) return;
  double bytes = 0;
  for (int64_t start : dataset.chunk_starts()) {
    std::error_code error;
    const auto size = fs::file_size(dataset.chunk_path(start), error);
    if (!error) bytes += static_cast<double>(size);
  }
  if (bytes <= static_cast<double>(data::kChunkCacheBytes)) return;
  spdlog::warn(
      "shuffling the whole split (training.chunks_per_shuffle 0, the official order) over {} chunk files ({:.1f} GB, "
      "the chunk cache holds {} MiB): about one chunk read per sample. Convert the split to the LVSM layout "
      "(`uplvsm dataset convert`), where a sample reads its frames alone, or set training.chunks_per_shuffle 2 "
      "(not the official order; docs/training.md)",
      dataset.chunk_starts().size(), bytes / 1e9, data::kChunkCacheBytes >> 20);
}

// Restricts the train split to the configured subset and checks it can serve this run (cameras, scene count).
void prepare_training_data(data::ChunkDataset& dataset, const Config& config, const TrainOptions& opt,
                           const model::NovelViewModelImpl& net) {
  const auto& tc = config.training;
  if (!tc.subset.empty()) {
    const auto subset = data::read_subset_manifest(tc.subset);
    dataset.keep_only(subset.scenes);
    spdlog::info("subset {} ({}): {} scenes{}", subset.name, tc.subset, dataset.size(),
                 subset.chunks.empty() ? "" : fmt::format(" in {} chunks", subset.chunks.size()));
  }
  const bool reads_cameras = model::resolve_target_poses(tc.target_poses, net) != model::TargetPoses::Estimator;
  for (int64_t i = 0; reads_cameras && i < dataset.size(); ++i)
    if (!dataset.poses_known(i))
      throw std::runtime_error(
          fmt::format("{} training reads ground-truth cameras, but scene {} of {} has none "
                      "(imported without poses, listed in train/unposed.json)",
                      to_string(config.model.variant), dataset.key(i), opt.data_root));
  if (tc.max_train_scenes > dataset.size())
    throw std::runtime_error(fmt::format("training.max_train_scenes = {}: the train split of {} has only {} scenes",
                                         tc.max_train_scenes, opt.data_root, dataset.size()));
  warn_if_shuffling_rereads_chunks(dataset, tc);
  if (tc.pose_noise_std > 0)
    spdlog::info("pose noise: N(0, {}^2) on the (t, q) of the input and target cameras (official noise_scale){}",
                 tc.pose_noise_std, reads_cameras ? "" : " (this UP-LVSM run never reads them)");
}

// The next `accumulation` micro-batches of the stream, on the device.
std::vector<MicroBatch> next_micro_batches(data::TrainingLoader& loader, int64_t accumulation, int64_t input_views,
                                           torch::Device device) {
  std::vector<MicroBatch> micro;
  for (int64_t i = 0; i < accumulation; ++i) micro.push_back(micro_batch(loader.next(), input_views, device));
  return micro;
}

// Smoothed loss/PSNR for the progress bar.
struct RunningMeans {
  double loss = -1, mse = -1;
  void add(const StepResult& r) {
    if (!std::isfinite(r.loss)) return;
    loss = loss < 0 ? r.loss : 0.95 * loss + 0.05 * r.loss;
    mse = mse < 0 ? r.mse : 0.95 * mse + 0.05 * r.mse;
  }
};

void log_step(std::ofstream& metrics, const TrainState& state, const StepResult& r, double step_seconds,
              const data::TrainingLoader& loader, const data::ChunkDataset& dataset) {
  // chunk_reads and resized_frames count from this invocation's start.
  metrics << json{{"step", state.step},
                  {"loss", r.loss},
                  {"mse", r.mse},
                  {"psnr", psnr_from_mse(r.mse)},
                  {"lr", r.lr},
                  {"grad_norm", r.grad_norm},
                  {"skipped", r.skipped},
                  {"step_seconds", step_seconds},
                  {"data_wait_seconds", loader.wait_seconds()},
                  {"chunk_reads", dataset.chunk_reads()},
                  {"resized_frames", loader.resized_frames()},
                  {"train_seconds", state.train_seconds}}
                 .dump()
          << "\n";
  metrics.flush();
}

// End of run: the loader's share, data-parallel consistency, and skipped updates.
void finish_run(const TrainState& state, const TrainingConfig& tc, Communicator* comm, model::NovelViewModelImpl& net,
                const data::TrainingLoader& loader, const data::ChunkDataset& dataset) {
  spdlog::info("data: {:.1f} s waiting on the loader, {} chunk files read, {} frame(s) of another size resized",
               loader.wait_seconds(), dataset.chunk_reads(), loader.resized_frames());
  if (comm) {
    check_parameters_in_sync(*comm, net.parameters());
    comm->barrier();  // rank 0's last checkpoint is on disk before any rank returns
    spdlog::info("rank {}: parameters identical on all {} ranks", comm->rank(), comm->world_size());
  }
  if (state.skipped_nonfinite + state.skipped_gradnorm > 0)
    spdlog::warn("skipped updates: {} non-finite losses, {} gradient norms above {} x clip", state.skipped_nonfinite,
                 state.skipped_gradnorm, tc.allowed_gradnorm_factor);
}

// What the run will do (train/run_plan.h), from the step it starts at.
void announce_training(const Config& config, const TrainOptions& opt, const data::ChunkDataset& dataset,
                       const data::LoaderOptions& loader_opt, const BatchPlan& batch, int64_t step) {
  const auto& tc = config.training;
  RunPlan plan;
  plan.config = config;
  plan.batch = batch;
  plan.device = opt.device.str();
  plan.perceptual_weights = opt.perceptual_weights;
  plan.init = step == 0 ? opt.init_weights : "";
  plan.resuming = step > 0;
  plan.data_root = opt.data_root;
  plan.scenes = tc.max_train_scenes > 0 ? std::min(tc.max_train_scenes, dataset.size()) : dataset.size();
  plan.split_scenes = dataset.size();
  plan.ordered_views = loader_opt.ordered_views;
  spdlog::info("training {}: steps {} -> {}", config.name, step, tc.train_steps);
  for (const auto& line : describe_run_plan(plan)) spdlog::info("  {}", line);
  // After the pre-flight checks, so that a run refused before it starts says so in one line.
  spdlog::info("  kernels: {}", kernels::describe_kernel_paths());
}

// Every rank starts from rank 0's weights.
void join_ranks(Communicator* comm, model::NovelViewModelImpl& net, const BatchPlan& batch) {
  if (!comm) return;
  comm->broadcast(net.parameters());
  spdlog::info("data parallel: rank {} of {} ({}), {} x {} scenes per rank and update", comm->rank(),
               comm->world_size(), comm->backend(), batch.per_micro_batch, batch.accumulation);
}

// Whether a signal stopped the run (its checkpoint is written by then); says so.
bool warn_if_interrupted(const StepResult& r, const std::string& checkpoint) {
  if (r.stop) spdlog::warn("signal {}: checkpoint written to {}, exiting", int(g_signal), checkpoint);
  return r.stop;
}

// The progress bar's fields for a step: smoothed loss and PSNR, and the step's learning rate.
void update_progress(ProgressBar& bar, int64_t step, const RunningMeans& means, const StepResult& r) {
  bar.update(step, {{"loss", fmt::format("{:.4f}", means.loss)},
                    {"psnr", fmt::format("{:.2f}", psnr_from_mse(means.mse))},
                    {"lr", fmt::format("{:.2e}", r.lr)}});
}

// What a step's end writes, besides the metrics line.
struct TrainedModel {
  model::NovelViewModel net;
  torch::optim::AdamW& optimizer;
};

// The periodic evaluation and the checkpoint when this step is due for them. Returns the checkpoint written, or "".
std::string evaluate_and_checkpoint(const TrainOptions& opt, const Config& config, TrainedModel m, TrainState& state,
                                    bool lead, std::ofstream& metrics, const std::string& checkpoint_dir,
                                    bool stop_now) {
  const auto& tc = config.training;
  const bool last = state.step == tc.train_steps;
  if (opt.periodic_eval && tc.eval_every > 0 && (state.step % tc.eval_every == 0 || last))
    run_periodic_eval(opt, m.net, state, lead, metrics);
  if (!lead || !(state.step % tc.checkpoint_every == 0 || last || stop_now)) return "";
  return save_training_checkpoint(checkpoint_dir, config, state, *m.net, m.optimizer, tc.keep_checkpoints);
}

bool already_finished(const std::string& run_dir, int64_t step, int64_t train_steps) {
  if (step < train_steps) return false;
  spdlog::info("run {} already finished ({} of {} steps)", run_dir, step, train_steps);
  return true;
}

}  // namespace

TrainResult train(const Config& config, const TrainOptions& opt) {
  const auto& tc = config.training;
  const auto t_start = std::chrono::steady_clock::now();
  Communicator* comm = opt.comm.get();
  const bool lead = !comm || comm->rank() == 0;                // the rank that writes files and shows progress
  require_perceptual_weights(config, opt.perceptual_weights);  // before anything is read or allocated
  require_tokenizer_start(config, opt.init_weights, run_resumes(opt.run_dir, opt.resume));
  const auto batch = plan_batch(tc, comm ? comm->world_size() : 1, config.name);
  check_memory_fits(config, opt.device);
  const auto files = prepare_run_dir(config, opt, lead);

  auto [net, optimizer, state] = start_model(config, opt, files.checkpoint_dir);
  if (lead) truncate_metrics(files.metrics, state.step);
  join_ranks(comm, *net, batch);
  TrainResult result;
  result.step = state.step;
  if (already_finished(opt.run_dir, state.step, tc.train_steps)) return result;

  data::ChunkDataset dataset(opt.data_root, "train");
  prepare_training_data(dataset, config, opt, *net);
  const auto loader_opt = loader_options(config, dataset, comm);
  if (lead) announce_training(config, opt, dataset, loader_opt, batch, state.step);
  // The stream is keyed to micro-batches: a run resumed at update s goes on with micro-batch s x accumulation.
  data::TrainingLoader loader(dataset, loader_opt, state.step * batch.accumulation);
  StepContext ctx = step_context(*net, *optimizer, config, opt);

  SignalScope signals;
  std::ofstream metrics;
  if (lead) metrics.open(files.metrics, std::ios::app);
  const bool show_progress = opt.progress && lead;
  ProgressBar bar("train", tc.train_steps, "step", state.step);
  RunningMeans means;
  const int64_t first_step = state.step;
  while (state.step < tc.train_steps) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto micro = next_micro_batches(loader, batch.accumulation, tc.num_input_views, opt.device);
    const auto r = train_step(ctx, state, micro, g_signal != 0);
    const double step_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    state.train_seconds += step_seconds;
    means.add(r);
    result.last_loss = r.loss;
    result.last_psnr = psnr_from_mse(r.mse);
    if (lead && (state.step % tc.log_every == 0 || state.step == tc.train_steps || state.step == first_step + 1))
      log_step(metrics, state, r, step_seconds, loader, dataset);
    if (show_progress) update_progress(bar, state.step, means, r);
    const bool stop_now = r.stop || (opt.stop_after_steps > 0 && state.step - first_step >= opt.stop_after_steps);
    auto saved =
        evaluate_and_checkpoint(opt, config, {net, *optimizer}, state, lead, metrics, files.checkpoint_dir, stop_now);
    if (!saved.empty()) result.last_checkpoint = saved;
    if (stop_now) {
      result.interrupted = warn_if_interrupted(r, result.last_checkpoint);
      break;
    }
  }
  if (show_progress) bar.finish();
  finish_run(state, tc, comm, *net, loader, dataset);
  result.step = state.step;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace uplvsm::train
