#include "uplvsm/train/run_start.h"

#include <filesystem>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/eval_mode.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/pretrained_weights.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/optimizer.h"

namespace uplvsm::train {

namespace {

void check_same_model(const Config& a, const Config& b, const std::string& source) {
  auto ja = config_to_json(a)["model"], jb = config_to_json(b)["model"];
  if (ja != jb)
    throw std::runtime_error(
        fmt::format("resume from {}: its model config differs from the given one\n  checkpoint: {}\n  "
                    "given:      {}",
                    source, jb.dump(), ja.dump()));
}

// A new run's starting weights; DINOv2 files go into the tokenizer like the official pretrained backbone.
// Returns whether the pose mapper still needs its initial fit (an UP-LVSM with one, from a file without it).
bool init_from_weights(model::NovelViewModelImpl& net, const std::string& path) {
  auto w = io::read_pretrained_weights(path);
  torch::NoGradGuard no_grad;
  const auto* up = model::as_uplvsm(net);
  const bool mapper = up && up->pose_mapper;
  io::LoadOptions load;
  if (mapper) load.allow_missing_substrings.push_back("pose_mapper.");
  auto report = w.source == io::WeightSource::Uplvsm ? io::load_state_dict(net, w.tensors, path, load)
                                                     : model::load_dinov2_into_tokenizer(net, w.tensors, path);
  spdlog::info("initialised from {} weights: {}", io::to_string(w.source), report.summary(path));
  return mapper && !w.tensors.count("pose_mapper.A");
}

// The camera-control stage starts from the least-squares map between real target poses and the latent poses the
// estimator gives them, on calibration batches drawn apart from the training stream (another seed).
void calibrate_pose_mapper(model::UPLVSMImpl& net, const Config& config, const TrainOptions& opt) {
  data::ChunkDataset dataset(opt.data_root, "train");
  auto lo = loader_options(config, dataset, nullptr);
  lo.seed += 1000003;
  const int64_t batches = std::max<int64_t>(1, (64 + lo.batch_size - 1) / lo.batch_size);
  torch::NoGradGuard no_grad;
  EvalModeGuard mode(net);
  std::vector<torch::Tensor> real, latent;
  const int64_t vi = config.training.num_input_views;
  for (int64_t i = 0; i < batches; ++i) {
    auto batch = data::make_training_batch(dataset, lo, i);
    auto dev = [&](const torch::Tensor& t) { return t.to(opt.device); };
    model::Views inputs{dev(batch.input_images(vi)), dev(batch.input_fxfycxcy(vi)), dev(batch.input_c2w(vi))};
    model::Views targets{dev(batch.target_images()), dev(batch.target_fxfycxcy()), dev(batch.target_c2w())};
    auto latents = net.encode_scene(inputs.images, inputs.fxfycxcy);
    latent.push_back(net.estimate_poses(targets.images, latents).reshape({-1, 7}).cpu());
    real.push_back(geometry::camera_control_poses(inputs.c2w, targets.c2w).reshape({-1, 7}).cpu());
  }
  const double rms = model::fit_pose_mapper(*net.pose_mapper, torch::cat(real), torch::cat(latent));
  spdlog::info("pose mapper: least-squares fit on {} target views (RMS residual {:.4f})", torch::cat(real).size(0),
               rms);
}

// The checkpoint to resume from: for "auto" the newest in the run that reads (none on a new run; a damaged newer
// one is skipped with a warning), a given file (damaged: an error), or none.
std::optional<io::CheckpointFile> resume_checkpoint(const TrainOptions& opt, const std::string& checkpoint_dir) {
  if (opt.resume == "none") return std::nullopt;
  if (opt.resume != "auto") return io::read_checkpoint(opt.resume);
  return read_newest_valid_checkpoint(checkpoint_dir);
}

// Restores weights, optimiser and training state from a checkpoint, or initialises a new run (optionally from
// weights).
ModelStart resume_or_initialise(model::NovelViewModel net, const Config& config, const TrainOptions& opt,
                                const std::string& checkpoint_dir) {
  auto optimizer = make_optimizer(*net, config.training);
  if (auto ckpt = resume_checkpoint(opt, checkpoint_dir)) {
    check_same_model(config, ckpt->config, ckpt->path);
    io::load_state_dict(*net, ckpt->model, ckpt->path);
    restore_optimizer_state(*optimizer, *net, ckpt->optimizer, ckpt->path);
    auto state = TrainState::from_json(ckpt->state);
    spdlog::info("resumed from {} at step {}", ckpt->path, state.step);
    return {net, std::move(optimizer), state};
  }
  if (!opt.init_weights.empty() && init_from_weights(*net, opt.init_weights))
    calibrate_pose_mapper(*model::as_uplvsm(*net), config, opt);
  return {net, std::move(optimizer), TrainState{}};
}

}  // namespace

bool run_resumes(const std::string& run_dir, const std::string& resume) {
  if (resume == "none") return false;
  if (resume != "auto") return true;
  return !training_checkpoints((std::filesystem::path(run_dir) / "checkpoints").string()).empty();
}

ModelStart start_model(const Config& config, const TrainOptions& opt, const std::string& checkpoint_dir) {
  torch::manual_seed(static_cast<uint64_t>(config.training.seed));
  auto net = model::make_model(config.model);
  net->to(opt.device);
  net->train();
  return resume_or_initialise(net, config, opt, checkpoint_dir);
}

}  // namespace uplvsm::train
