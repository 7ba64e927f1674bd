#include "uplvsm/study/pose_probe.h"

#include <fstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/geometry/quaternion.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/model/pose_mapper.h"

namespace uplvsm::study {

using torch::indexing::Slice;

namespace {

torch::Tensor latent_poses_of_scene(model::UPLVSM& net, const data::SceneViews& views, int64_t chunk,
                                    torch::Device device) {
  auto images = views.images.unsqueeze(0).to(device), k = views.fxfycxcy.unsqueeze(0).to(device);
  auto latents = net->encode_scene(images.narrow(1, 0, 2), k.narrow(1, 0, 2));
  std::vector<torch::Tensor> poses;
  for (int64_t s = 0; s < images.size(1); s += chunk) {
    const int64_t n = std::min(chunk, images.size(1) - s);
    poses.push_back(net->estimate_poses(images.narrow(1, s, n), latents)[0].cpu());
  }
  // Expressed like the real poses: relative to the first context view, translations in the context baseline. The
  // estimator's latent frame is the scene latents' own (its origin and scale differ per scene), so a probe of the
  // absolute latent poses would have to learn each scene's frame from a single view.
  auto c2w = geometry::pose_encoding_to_c2w(torch::cat(poses).to(torch::kFloat64)).unsqueeze(0);
  return geometry::camera_control_poses(c2w.narrow(1, 0, 2), c2w)[0].to(torch::kFloat64);
}

// Quaternions with w >= 0 (q and -q are one rotation), so a regression has one target per rotation.
torch::Tensor canonical_sign(const torch::Tensor& pose) {
  auto q = pose.index({Slice(), Slice(3, 7)});
  auto sign = torch::where(q.index({Slice(), 3}) < 0, -torch::ones_like(q.index({Slice(), 3})),
                           torch::ones_like(q.index({Slice(), 3})));
  return torch::cat({pose.index({Slice(), Slice(0, 3)}), q * sign.unsqueeze(1)}, 1);
}

torch::Tensor normalize_output(const torch::Tensor& pose) {
  auto q = pose.index({Slice(), Slice(3, 7)});
  return torch::cat({pose.index({Slice(), Slice(0, 3)}), q / q.norm(2, 1, true).clamp_min(1e-9)}, 1);
}

double median_of(const torch::Tensor& x) { return x.numel() == 0 ? 0.0 : x.median().item<double>(); }

}  // namespace

PosePairs collect_pose_pairs(model::UPLVSM& net, const data::ChunkDataset& dataset, const data::PreprocessOptions& prep,
                             const PosePairOptions& opt) {
  TORCH_CHECK(opt.gap >= 1, "pose pairs: gap must be >= 1");
  torch::NoGradGuard no_grad;
  EvalModeGuard mode(*net);
  const int64_t scenes = opt.max_scenes > 0 ? std::min(opt.max_scenes, dataset.size()) : dataset.size();
  PosePairs out;
  std::vector<torch::Tensor> latent, real;
  ProgressBar bar("pose pairs", scenes, "scene");
  for (int64_t i = 0; i < scenes; ++i) {
    const int64_t n = dataset.num_frames(i);
    const int64_t gap = std::min(opt.gap, n - 1);
    if (gap < 1) {
      spdlog::warn("pose pairs: skipping scene {} ({} frame)", dataset.key(i), n);
      ++out.skipped_scenes;
      continue;
    }
    std::vector<int64_t> frames = {0, gap};
    for (int64_t f = 1; f < gap; ++f) frames.push_back(f);
    data::SceneViews views;
    try {
      views = dataset.load_views(i, frames, prep);
    } catch (const data::BadFrameError& e) {
      spdlog::warn("pose pairs: skipping scene {}: {}", dataset.key(i), e.what());
      ++out.skipped_scenes;
      continue;
    }
    latent.push_back(latent_poses_of_scene(net, views, opt.chunk, opt.device));
    auto c2w = views.c2w.unsqueeze(0);
    real.push_back(geometry::camera_control_poses(c2w.narrow(1, 0, 2), c2w)[0].to(torch::kFloat64));
    for (int64_t f : frames) {
      out.scenes.push_back(dataset.key(i));
      out.frames.push_back(f);
    }
    bar.update(i + 1);
  }
  bar.finish();
  if (latent.empty()) throw std::runtime_error("pose pairs: no usable scene in split " + dataset.split());
  out.latent = torch::cat(latent);
  out.real = torch::cat(real);
  return out;
}

void write_pose_pairs_csv(const std::string& path, const PosePairs& p) {
  std::string text =
      "scene,frame,latent_tx,latent_ty,latent_tz,latent_qx,latent_qy,latent_qz,latent_qw,real_tx,"
      "real_ty,real_tz,real_qx,real_qy,real_qz,real_qw\n";
  auto l = p.latent.contiguous(), r = p.real.contiguous();
  for (size_t i = 0; i < p.scenes.size(); ++i) {
    text += fmt::format("{},{}", p.scenes[i], p.frames[i]);
    for (int64_t j = 0; j < 7; ++j) text += fmt::format(",{:.6f}", l[i][j].item<double>());
    for (int64_t j = 0; j < 7; ++j) text += fmt::format(",{:.6f}", r[i][j].item<double>());
    text += "\n";
  }
  io::write_file_atomic(path, text.data(), text.size());
}

PosePairs without_canonical_views(const PosePairs& p) {
  std::vector<int64_t> keep;
  for (size_t i = 0; i < p.frames.size(); ++i)
    if (p.frames[i] != 0) keep.push_back(static_cast<int64_t>(i));
  auto index = torch::tensor(keep, torch::kInt64);
  PosePairs out;
  out.latent = p.latent.index_select(0, index);
  out.real = p.real.index_select(0, index);
  for (int64_t i : keep) {
    out.scenes.push_back(p.scenes[i]);
    out.frames.push_back(p.frames[i]);
  }
  out.skipped_scenes = p.skipped_scenes;
  return out;
}

PoseAccuracy pose_accuracy(const torch::Tensor& predicted, const torch::Tensor& real) {
  TORCH_CHECK(predicted.sizes() == real.sizes() && predicted.dim() == 2 && predicted.size(1) == 7,
              "pose_accuracy: expected two [N, 7] tensors, got ", predicted.sizes(), " and ", real.sizes());
  auto p = normalize_output(predicted.to(torch::kFloat64)), r = normalize_output(real.to(torch::kFloat64));
  auto t_err = (p.index({Slice(), Slice(0, 3)}) - r.index({Slice(), Slice(0, 3)})).norm(2, 1);
  auto dot = (p.index({Slice(), Slice(3, 7)}) * r.index({Slice(), Slice(3, 7)})).sum(1).abs().clamp_max(1.0);
  auto r_err = 2.0 * torch::acos(dot) * (180.0 / M_PI);
  PoseAccuracy a;
  a.views = p.size(0);
  for (double t : a.translation_thresholds)
    a.translation_accuracy.push_back((t_err < t).to(torch::kFloat64).mean().item<double>());
  for (double d : a.rotation_thresholds_deg)
    a.rotation_accuracy.push_back((r_err < d).to(torch::kFloat64).mean().item<double>());
  a.median_translation_error = median_of(t_err);
  a.median_rotation_error_deg = median_of(r_err);
  return a;
}

nlohmann::json to_json(const PoseAccuracy& a) {
  nlohmann::json j{{"views", a.views},
                   {"median_translation_error", a.median_translation_error},
                   {"median_rotation_error_deg", a.median_rotation_error_deg}};
  for (size_t i = 0; i < a.translation_thresholds.size(); ++i)
    j[fmt::format("trans@{:g}", a.translation_thresholds[i])] = a.translation_accuracy[i];
  for (size_t i = 0; i < a.rotation_thresholds_deg.size(); ++i)
    j[fmt::format("rot@{:g}", a.rotation_thresholds_deg[i])] = a.rotation_accuracy[i];
  return j;
}

torch::Tensor fit_and_apply_linear_probe(const PosePairs& train, const torch::Tensor& latent) {
  // The same least-squares solver as the camera mapper, in the other direction: latent -> real.
  model::PoseMapper probe;
  model::fit_pose_mapper(*probe, train.latent, canonical_sign(train.real), 1e-6);
  torch::NoGradGuard no_grad;
  return probe->forward(latent.to(torch::kFloat32)).to(torch::kFloat64);
}

torch::Tensor mean_pose_baseline(const PosePairs& train, int64_t views) {
  auto mean = normalize_output(canonical_sign(train.real).mean(0, true));
  return mean.expand({views, 7}).clone();
}

torch::Tensor fit_and_apply_mlp_probe(const PosePairs& train, const torch::Tensor& latent, const ProbeOptions& o) {
  torch::manual_seed(o.seed);
  torch::nn::Sequential mlp(torch::nn::Linear(7, o.hidden), torch::nn::ReLU(), torch::nn::Linear(o.hidden, 7));
  mlp->to(torch::kFloat64);
  // Inputs standardised with the training statistics, so one learning rate fits any latent scale.
  auto mean = train.latent.mean(0), std = train.latent.std(0).clamp_min(1e-6);
  auto x = (train.latent - mean) / std, y = canonical_sign(train.real);
  torch::optim::Adam adam(mlp->parameters(), torch::optim::AdamOptions(o.lr));
  ProgressBar bar("mlp probe", o.iterations, "step");
  for (int64_t it = 0; it < o.iterations; ++it) {
    adam.zero_grad();
    auto out = mlp->forward(x);
    auto loss = torch::mse_loss(out, y);
    loss.backward();
    adam.step();
    bar.update(it + 1);
  }
  bar.finish();
  torch::NoGradGuard no_grad;
  return normalize_output(mlp->forward((latent.to(torch::kFloat64) - mean) / std));
}

}  // namespace uplvsm::study
