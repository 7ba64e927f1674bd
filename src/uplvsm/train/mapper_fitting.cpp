#include "uplvsm/train/mapper_fitting.h"

#include <chrono>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/model/eval_mode.h"
#include "uplvsm/train/optimizer.h"

namespace uplvsm::train {

namespace {

// What the fit reads of the model, per target view: its real pose, what the mapper reads of its scene, and the latent
// pose the estimator gives its image ([N, 7], [N, 14], [N, 7] on the CPU).
struct PosePairs {
  std::vector<torch::Tensor> real, scene, latent;
  int64_t views = 0, skipped = 0;
};

// The samples of `batch` whose inputs have a baseline (camera-control units divide by it).
torch::Tensor samples_with_baseline(const data::TrainingBatch& batch, int64_t vi) {
  if (vi < 2) return torch::arange(batch.images.size(0));
  using torch::indexing::Slice;
  auto t = batch.input_c2w(vi).index({Slice(), Slice(0, 2), Slice(0, 3), 3});
  return torch::nonzero((t.select(1, 1) - t.select(1, 0)).norm(2, -1) > 1e-6).flatten();
}

void add_batch(model::UPLVSMImpl& net, const data::TrainingBatch& batch, int64_t vi, const MapperFitOptions& opt,
               PosePairs& pairs) {
  auto keep = samples_with_baseline(batch, vi);
  pairs.skipped += batch.images.size(0) - keep.size(0);
  if (keep.size(0) == 0) return;
  auto dev = [&](const torch::Tensor& t) { return t.index_select(0, keep).to(opt.device); };
  torch::NoGradGuard no_grad;
  AutocastGuard amp(opt.device, opt.bf16);
  auto inputs = dev(batch.input_images(vi));
  auto latents = net.encode_scene(inputs, dev(batch.input_fxfycxcy(vi)));
  auto real = geometry::camera_control_poses(dev(batch.input_c2w(vi)), dev(batch.target_c2w()));  // [b, t, 7]
  auto scene = model::scene_conditioning(net.estimate_poses(inputs, latents));                   // [b, 14]
  const int64_t b = real.size(0), t = real.size(1);
  pairs.real.push_back(real.reshape({-1, 7}).cpu());
  pairs.scene.push_back(scene.unsqueeze(1).expand({b, t, scene.size(1)}).reshape({b * t, -1}).cpu());
  pairs.latent.push_back(
      net.estimate_poses(dev(batch.target_images()), latents).reshape({-1, 7}).to(torch::kCPU, torch::kFloat32));
  pairs.views += b * t;
}

// Posed samples drawn as training draws them (another seed than a training run's stream) until there are
// calibration_views target views; batches enough for four times that at most, so that a dataset whose samples are
// all skipped ends.
PosePairs collect_pairs(model::UPLVSMImpl& net, const data::ChunkDataset& dataset, const MapperFitOptions& opt) {
  auto lo = opt.loader;
  lo.seed += 1000003;
  const int64_t per_batch = std::max<int64_t>(1, lo.batch_size * lo.num_target_views);
  const int64_t max_batches = 4 * ((opt.calibration_views + per_batch - 1) / per_batch) + 8;
  PosePairs pairs;
  ProgressBar bar("fit-mapper: reading poses", opt.calibration_views, "view");
  for (int64_t i = 0; pairs.views < opt.calibration_views && i < max_batches; ++i) {
    add_batch(net, data::make_training_batch(dataset, lo, i), lo.num_input_views, opt, pairs);
    bar.update(std::min(pairs.views, opt.calibration_views));
  }
  bar.finish();
  if (pairs.views == 0)
    throw std::runtime_error(fmt::format("fit-mapper: no sample of {} has two input views apart (every input pair "
                                         "coincides, so there is no baseline to measure the cameras in)",
                                         dataset.root()));
  return pairs;
}

// The MLP mapper (and its linear part) by full-batch Adam on the pairs, from the least-squares start.
double regress(model::PoseMapperImpl& mapper, const PosePairs& pairs, const MapperFitOptions& opt) {
  auto dev = [&](const std::vector<torch::Tensor>& t) { return torch::cat(t).to(opt.device, torch::kFloat32); };
  auto real = dev(pairs.real), scene = dev(pairs.scene), latent = dev(pairs.latent);
  torch::optim::Adam adam(mapper.parameters(), torch::optim::AdamOptions(opt.regression_lr));
  const int64_t steps = opt.regression_steps;
  for (int64_t i = 0; i < steps; ++i) {
    set_learning_rate(adam, opt.regression_lr * lr_lambda(i, std::max<int64_t>(1, steps / 20), steps));
    adam.zero_grad();
    auto loss = (mapper.forward(real, scene) - latent).pow(2).mean();
    loss.backward();
    adam.step();
  }
  torch::NoGradGuard no_grad;
  return std::sqrt((mapper.forward(real, scene) - latent).pow(2).mean().item<double>());
}

// Research: the mapper alone trained on the rendering error at real cameras, through the frozen model.
class FrozenParameters {
 public:
  explicit FrozenParameters(torch::nn::Module& net) {
    for (auto& p : net.parameters()) {
      flags_.emplace_back(p, p.requires_grad());
      p.set_requires_grad(false);
    }
  }
  ~FrozenParameters() {
    for (auto& [p, flag] : flags_) p.set_requires_grad(flag);
  }

 private:
  std::vector<std::pair<torch::Tensor, bool>> flags_;
};

double render_step(model::UPLVSMImpl& net, model::PoseMapperImpl& mapper, torch::optim::Adam& adam,
                   const data::TrainingBatch& batch, const MapperFitOptions& opt) {
  const int64_t vi = opt.loader.num_input_views;
  auto dev = [&](const torch::Tensor& t) { return t.to(opt.device); };
  torch::Tensor latents, scene, real, targets = dev(batch.target_images());
  {
    torch::NoGradGuard no_grad;
    AutocastGuard amp(opt.device, opt.bf16);
    auto inputs = dev(batch.input_images(vi));
    latents = net.encode_scene(inputs, dev(batch.input_fxfycxcy(vi)));
    scene = model::scene_conditioning(net.estimate_poses(inputs, latents));
    real = geometry::camera_control_poses(dev(batch.input_c2w(vi)), dev(batch.target_c2w()));
  }
  adam.zero_grad();
  auto poses = mapper.forward(real, scene);
  torch::Tensor render;
  {
    AutocastGuard amp(opt.device, opt.bf16);
    render = net.render_views(latents, poses, dev(batch.target_fxfycxcy()), targets.size(3), targets.size(4));
  }
  auto loss = torch::mse_loss(render.to(torch::kFloat32), targets);
  loss.backward();
  torch::nn::utils::clip_grad_norm_(mapper.parameters(), 1.0);
  adam.step();
  return loss.item<double>();
}

void train_through_model(model::UPLVSMImpl& net, model::PoseMapperImpl& mapper, const data::ChunkDataset& dataset,
                         const MapperFitOptions& opt) {
  FrozenParameters frozen(net);
  torch::optim::Adam adam(mapper.parameters(), torch::optim::AdamOptions(opt.render_lr).betas({0.9, 0.99}));
  data::TrainingLoader loader(dataset, opt.loader, 0);
  ProgressBar bar("fit-mapper: through the model", opt.render_steps, "step");
  double recent = 0;
  for (int64_t step = 0; step < opt.render_steps; ++step) {
    set_learning_rate(adam, opt.render_lr * lr_lambda(step, 30, opt.render_steps));
    const double loss = render_step(net, mapper, adam, loader.next(), opt);
    recent = step == 0 ? loss : 0.95 * recent + 0.05 * loss;
    bar.update(step + 1, {{"mse", fmt::format("{:.5f}", recent)}});
  }
  bar.finish();
}

void check_posed(const data::ChunkDataset& dataset, int64_t scenes) {
  for (int64_t i = 0; i < scenes; ++i)
    if (!dataset.poses_known(i))
      throw std::runtime_error(fmt::format(
          "fit-mapper: scene {} of {} has no cameras (imported without poses, listed in {}/unposed.json); a "
          "mapper is fitted to real cameras: import a COLMAP or transforms.json reconstruction of it",
          dataset.key(i), dataset.root(), dataset.split()));
}

}  // namespace

nlohmann::json MapperFitReport::to_json() const {
  return {{"scenes", scenes},       {"calibration_views", calibration_views},
          {"least_squares_rms", least_squares_rms}, {"fit_rms", fit_rms},
          {"skipped_samples", skipped_samples},     {"seconds", seconds}};
}

MapperFitReport fit_mapper_to_model(model::UPLVSMImpl& net, model::PoseMapperImpl& mapper,
                                    const data::ChunkDataset& dataset, const MapperFitOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  MapperFitReport report;
  report.scenes = opt.loader.max_scenes > 0 ? std::min(opt.loader.max_scenes, dataset.size()) : dataset.size();
  if (report.scenes == 0) throw std::runtime_error("fit-mapper: " + dataset.root() + " has no scenes");
  check_posed(dataset, report.scenes);
  model::EvalModeGuard mode(net);
  mapper.to(opt.device);
  const auto pairs = collect_pairs(net, dataset, opt);
  report.calibration_views = pairs.views;
  report.skipped_samples = pairs.skipped;
  if (pairs.skipped > 0)
    spdlog::warn("fit-mapper: skipped {} samples whose two input views coincide (no baseline)", pairs.skipped);
  report.least_squares_rms = model::fit_pose_mapper(mapper, torch::cat(pairs.real), torch::cat(pairs.latent));
  report.fit_rms = mapper.reads_scene() ? regress(mapper, pairs, opt) : report.least_squares_rms;
  spdlog::info("pose mapper: fitted to {} target views (least-squares RMS {:.4f}, {} mapper RMS {:.4f} latent units)",
               pairs.views, report.least_squares_rms, model::to_string(mapper.options.kind), report.fit_rms);
  if (opt.render_steps > 0) train_through_model(net, mapper, dataset, opt);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace uplvsm::train
