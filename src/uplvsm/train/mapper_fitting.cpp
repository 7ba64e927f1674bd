#include "uplvsm/train/mapper_fitting.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/view_sampler.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/io/state_dict.h"
#include "uplvsm/train/optimizer.h"

namespace uplvsm::train {

namespace {

// What the fit reads of the model, per target view: its real pose, what the mapper reads of its scene, and the latent
// pose the estimator gives its image ([N, 7], [N, 14], [N, 7] on the CPU).
struct PosePairs {
  std::vector<torch::Tensor> real, scene, latent;
  std::vector<int64_t> row_scene;  // the dataset index of each row's scene
  int64_t views = 0, skipped = 0;
};

// The samples of `batch` whose inputs have a baseline (camera-control units divide by it).
torch::Tensor samples_with_baseline(const data::TrainingBatch& batch, int64_t vi) {
  if (vi < 2) return torch::arange(batch.images.size(0));
  using torch::indexing::Slice;
  auto t = batch.input_c2w(vi).index({Slice(), Slice(0, 2), Slice(0, 3), 3});
  return torch::nonzero((t.select(1, 1) - t.select(1, 0)).norm(2, -1) > 1e-6).flatten();
}

void add_batch(model::UPLVSMImpl& net, const data::ChunkDataset& dataset, const data::TrainingBatch& batch, int64_t vi,
               const MapperFitOptions& opt, PosePairs& pairs) {
  auto keep = samples_with_baseline(batch, vi);
  pairs.skipped += batch.images.size(0) - keep.size(0);
  if (keep.size(0) == 0) return;
  auto dev = [&](const torch::Tensor& t) { return t.index_select(0, keep).to(opt.device); };
  torch::NoGradGuard no_grad;
  Bf16Autocast amp(opt.device, opt.bf16);
  auto inputs = dev(batch.input_images(vi));
  auto latents = net.encode_scene(inputs, dev(batch.input_fxfycxcy(vi)));
  auto real = geometry::camera_control_poses(dev(batch.input_c2w(vi)), dev(batch.target_c2w()));  // [b, t, 7]
  auto scene = model::scene_conditioning(net.estimate_poses(inputs, latents));                    // [b, 14]
  const int64_t b = real.size(0), t = real.size(1);
  pairs.real.push_back(real.reshape({-1, 7}).cpu());
  pairs.scene.push_back(scene.unsqueeze(1).expand({b, t, scene.size(1)}).reshape({b * t, -1}).cpu());
  pairs.latent.push_back(
      net.estimate_poses(dev(batch.target_images()), latents).reshape({-1, 7}).to(torch::kCPU, torch::kFloat32));
  pairs.views += b * t;
  for (int64_t i = 0; i < b; ++i)
    pairs.row_scene.insert(pairs.row_scene.end(), t, dataset.find(batch.keys[keep[i].item<int64_t>()]));
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
    add_batch(net, dataset, data::make_training_batch(dataset, lo, i), lo.num_input_views, opt, pairs);
    bar.update(std::min(pairs.views, opt.calibration_views));
  }
  bar.finish();
  if (pairs.views == 0)
    throw std::runtime_error(
        fmt::format("fit-mapper: no sample of {} has two input views apart (every input pair "
                    "coincides, so there is no baseline to measure the cameras in)",
                    dataset.root()));
  return pairs;
}

// Rows of the pairs fitted and held out of the MLP's steps, by scene (held_out_scene): a check on other views of
// the fitted scenes could not show a map over-fitted to a few scenes.
struct Split {
  torch::Tensor fit, held_out;
};
Split split_by_scene(const PosePairs& pairs, int64_t scenes) {
  std::vector<int64_t> fit, held_out;
  for (int64_t row = 0; row < static_cast<int64_t>(pairs.row_scene.size()); ++row)
    (held_out_scene(pairs.row_scene[row], scenes) ? held_out : fit).push_back(row);
  if (fit.empty()) std::swap(fit, held_out);  // a draw that met only held-out scenes: no check rather than no fit
  return {torch::tensor(fit, torch::kInt64), torch::tensor(held_out, torch::kInt64)};
}

// The MLP mapper (and its linear part) by full-batch Adam on the pairs, from the least-squares start; the parameters
// kept are those of the check (every 100 steps) with the lowest held-out residual, so that a few scenes do not end
// in an over-fitted map.
void regress(model::PoseMapperImpl& mapper, const PosePairs& pairs, const Split& split, const MapperFitOptions& opt,
             MapperFitReport& report) {
  auto all = [&](const std::vector<torch::Tensor>& t) { return torch::cat(t).to(opt.device, torch::kFloat32); };
  auto real = all(pairs.real), scene = all(pairs.scene), latent = all(pairs.latent);
  auto rms = [&](const torch::Tensor& rows) {
    torch::NoGradGuard no_grad;
    auto r = rows.to(opt.device);
    return std::sqrt(
        (mapper.forward(real.index({r}), scene.index({r})) - latent.index({r})).pow(2).mean().item<double>());
  };
  const bool checked = split.held_out.numel() > 0;
  auto fit_rows = split.fit.to(opt.device);
  auto x = real.index({fit_rows}), s = scene.index({fit_rows}), y = latent.index({fit_rows});
  torch::optim::Adam adam(mapper.parameters(), torch::optim::AdamOptions(opt.regression_lr));
  const int64_t steps = opt.regression_steps;
  // state_dict's CPU tensors share the parameters' storage: the kept state is a copy.
  auto snapshot = [&] {
    auto state = io::state_dict(mapper);
    for (auto& [name, t] : state) t = t.clone();
    return state;
  };
  double best = checked ? rms(split.held_out) : 0;
  report.start_held_out_rms = checked ? best : std::nan("");
  auto best_state = snapshot();
  for (int64_t i = 0; i < steps; ++i) {
    set_learning_rate(adam, opt.regression_lr * lr_lambda(i, std::max<int64_t>(1, steps / 20), steps));
    adam.zero_grad();
    (mapper.forward(x, s) - y).pow(2).mean().backward();
    adam.step();
    if (checked && ((i + 1) % 100 == 0 || i + 1 == steps)) {
      const double now = rms(split.held_out);
      if (now < best) {
        best = now;
        best_state = snapshot();
      }
    }
  }
  if (checked) io::load_state_dict(mapper, best_state, "the best held-out check");
  report.fit_rms = rms(split.fit);
  report.held_out_rms = checked ? rms(split.held_out) : std::nan("");
}

void check_posed(const data::ChunkDataset& dataset, int64_t scenes) {
  for (int64_t i = 0; i < scenes; ++i)
    if (!dataset.poses_known(i))
      throw std::runtime_error(fmt::format(
          "fit-mapper: scene {} of {} has no cameras (imported without poses, listed in {}/unposed.json); a "
          "mapper is fitted to real cameras: import a COLMAP or transforms.json reconstruction of it",
          dataset.key(i), dataset.root(), dataset.split()));
}

// Every scene too short for the view sampling would only be skipped, one warning each: say so once, with the fix.
void check_some_scene_fits(const data::ChunkDataset& dataset, int64_t scenes, const data::LoaderOptions& lo) {
  if (!lo.ordered_views) return;
  int64_t longest = 0;
  for (int64_t i = 0; i < scenes; ++i) {
    longest = std::max(longest, dataset.num_frames(i));
    if (data::can_sample(dataset.num_frames(i), lo.num_views, lo.min_frame_dist)) return;
  }
  throw std::runtime_error(fmt::format(
      "fit-mapper: no scene of {} is long enough for {} views with the inputs more than {} frames apart (the longest "
      "has {} frames): give input distances that fit the scenes (--min-frame-dist, --max-frame-dist) or fewer "
      "targets (--targets)",
      dataset.root(), lo.num_views, lo.min_frame_dist, longest));
}

// The keys of the scenes whose rows are held out, in dataset order.
std::vector<std::string> held_out_keys(const data::ChunkDataset& dataset, const PosePairs& pairs, const Split& split) {
  std::vector<int64_t> scenes;
  for (int64_t i = 0; i < split.held_out.numel(); ++i)
    scenes.push_back(pairs.row_scene[split.held_out[i].item<int64_t>()]);
  std::sort(scenes.begin(), scenes.end());
  scenes.erase(std::unique(scenes.begin(), scenes.end()), scenes.end());
  std::vector<std::string> keys;
  for (auto i : scenes) keys.push_back(dataset.key(i));
  return keys;
}

}  // namespace

bool held_out_scene(int64_t scene, int64_t scenes) {
  if (scenes < 2) return false;
  if (scenes < 10) return scene == scenes - 1;
  return scene % 10 == 9;
}

nlohmann::json MapperFitReport::to_json() const {
  return {{"scenes", scenes},
          {"calibration_views", calibration_views},
          {"least_squares_rms", least_squares_rms},
          {"fit_rms", fit_rms},
          {"held_out_rms", std::isfinite(held_out_rms) ? nlohmann::json(held_out_rms) : nlohmann::json()},
          {"held_out_scenes", held_out_scenes},
          {"held_out_views", held_out_views},
          {"skipped_samples", skipped_samples},
          {"seconds", seconds}};
}

MapperFitReport fit_mapper_to_model(model::UPLVSMImpl& net, model::PoseMapperImpl& mapper,
                                    const data::ChunkDataset& dataset, const MapperFitOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  MapperFitReport report;
  report.scenes = opt.loader.max_scenes > 0 ? std::min(opt.loader.max_scenes, dataset.size()) : dataset.size();
  if (report.scenes == 0) throw std::runtime_error("fit-mapper: " + dataset.root() + " has no scenes");
  check_posed(dataset, report.scenes);
  check_some_scene_fits(dataset, report.scenes, opt.loader);
  EvalModeGuard mode(net);
  mapper.to(opt.device);
  const auto pairs = collect_pairs(net, dataset, opt);
  report.calibration_views = pairs.views;
  report.skipped_samples = pairs.skipped;
  if (pairs.skipped > 0)
    spdlog::warn("fit-mapper: skipped {} samples whose two input views coincide (no baseline)", pairs.skipped);
  if (mapper.reads_scene()) {
    // The held-out scenes are kept out of the least-squares start too: its check would otherwise have seen them.
    const auto split = split_by_scene(pairs, report.scenes);
    report.held_out_scenes = held_out_keys(dataset, pairs, split);
    report.held_out_views = split.held_out.numel();
    report.least_squares_rms = model::fit_pose_mapper(mapper, torch::cat(pairs.real).index({split.fit}),
                                                      torch::cat(pairs.latent).index({split.fit}));
    regress(mapper, pairs, split, opt, report);
  } else {
    report.least_squares_rms = model::fit_pose_mapper(mapper, torch::cat(pairs.real), torch::cat(pairs.latent));
    report.fit_rms = report.least_squares_rms;
  }
  // A linear mapper is its least-squares fit: it holds nothing out, so it has no held-out figure to print.
  const std::string check = report.held_out_views > 0
                                ? fmt::format("; {:.4f} on {} views of {} held-out scenes", report.held_out_rms,
                                              report.held_out_views, report.held_out_scenes.size())
                                : "";
  spdlog::info(
      "pose mapper: fitted to {} target views (least-squares RMS {:.4f}; {} mapper RMS {:.4f}{}; latent units)",
      pairs.views, report.least_squares_rms, model::to_string(mapper.options.kind), report.fit_rms, check);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

}  // namespace uplvsm::train
