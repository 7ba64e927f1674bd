#include "uplvsm/study/pose_sensitivity.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::study {

namespace {

// The views of one scene, frames {0, gap, 1, ..., gap-1}: the two inputs first, every frame a target.
void measure_scene(model::UPLVSM& net, const data::SceneViews& views, const std::string& key,
                   const std::vector<int64_t>& frames, const SensitivityOptions& opt, SensitivityReport& out) {
  auto images = views.images.unsqueeze(0).to(opt.device), k = views.fxfycxcy.unsqueeze(0).to(opt.device);
  auto c2w = views.c2w.defined() ? views.c2w.unsqueeze(0).to(opt.device) : torch::Tensor();
  auto first_two = [](const torch::Tensor& x) { return x.defined() ? x.narrow(1, 0, 2) : x; };
  model::Views inputs{first_two(images), first_two(k), first_two(c2w)};
  model::Views targets{images, k, c2w};
  const int64_t H = images.size(3), W = images.size(4);
  auto latents = net->encode_scene(inputs.images, inputs.fxfycxcy);
  auto poses = net->target_latent_poses(inputs, targets, latents, opt.source).to(latents.device());
  auto own = net->render_views(latents, poses, k, H, W).to(torch::kFloat32);
  auto at_first =
      net->render_views(latents, poses.narrow(1, 0, 1).expand_as(poses).contiguous(), k, H, W).to(torch::kFloat32);
  auto psnr = eval::psnr(own, images)[0].cpu();
  auto edges = eval::gradient_energy_ratio(own, images)[0].cpu();
  auto render_change = (own - at_first).abs().mean({-3, -2, -1})[0].to(torch::kCPU, torch::kFloat64);
  auto truth_change = (images - images.narrow(1, 0, 1)).abs().mean({-3, -2, -1})[0].to(torch::kCPU, torch::kFloat64);
  for (size_t j = 0; j < frames.size(); ++j) {
    const auto i = static_cast<int64_t>(j);
    out.views.push_back({key, frames[j], j < 2, psnr[i].item<double>(), edges[i].item<double>(),
                         render_change[i].item<double>(), truth_change[i].item<double>()});
  }
}

struct Means {
  double psnr = 0, grad_ratio = 0, render_change = 0, truth_change = 0;
  int64_t views = 0;
};

template <class Keep>
Means means_of(const SensitivityReport& r, Keep keep) {
  Means m;
  for (const auto& v : r.views) {
    if (!keep(v)) continue;
    m.psnr += v.psnr, m.grad_ratio += v.grad_ratio, m.render_change += v.render_change;
    m.truth_change += v.truth_change, ++m.views;
  }
  if (m.views == 0) return m;
  const double n = static_cast<double>(m.views);
  m.psnr /= n, m.grad_ratio /= n, m.render_change /= n, m.truth_change /= n;
  return m;
}

nlohmann::json to_json(const Means& m) {
  const double sensitivity = m.truth_change > 0 ? m.render_change / m.truth_change : 0.0;
  return {{"views", m.views},
          {"psnr", m.psnr},
          {"grad_ratio", m.grad_ratio},
          {"render_change", m.render_change},
          {"truth_change", m.truth_change},
          {"sensitivity", sensitivity}};
}

}  // namespace

SensitivityReport measure_pose_sensitivity(model::UPLVSM& net, const data::ChunkDataset& dataset,
                                           const data::PreprocessOptions& prep, const SensitivityOptions& opt) {
  TORCH_CHECK(opt.gap >= 1, "pose sensitivity: gap must be >= 1");
  torch::NoGradGuard no_grad;
  EvalModeGuard mode(*net);
  const int64_t scenes = opt.max_scenes > 0 ? std::min(opt.max_scenes, dataset.size()) : dataset.size();
  SensitivityReport out;
  ProgressBar bar("pose sensitivity", scenes, "scene");
  for (int64_t i = 0; i < scenes; ++i) {
    const int64_t gap = std::min(opt.gap, dataset.num_frames(i) - 1);
    std::vector<int64_t> frames = {0, gap};
    for (int64_t f = 1; f < gap; ++f) frames.push_back(f);
    try {
      if (gap < 1) throw std::runtime_error("a single frame");
      measure_scene(net, dataset.load_views(i, frames, prep), dataset.key(i), frames, opt, out);
    } catch (const std::runtime_error& e) {  // data::BadFrameError and too-short scenes
      spdlog::warn("pose sensitivity: skipping scene {}: {}", dataset.key(i), e.what());
      ++out.skipped_scenes;
    }
    bar.update(i + 1);
  }
  bar.finish();
  if (out.views.empty()) throw std::runtime_error("pose sensitivity: no usable scene in split " + dataset.split());
  return out;
}

nlohmann::json summarise(const SensitivityReport& r) {
  auto moved = means_of(r, [](const SensitivityView& v) { return v.frame != 0; });
  auto targets = means_of(r, [](const SensitivityView& v) { return !v.input; });
  auto inputs = means_of(r, [](const SensitivityView& v) { return v.input; });
  return {{"all_but_first_input", to_json(moved)},
          {"targets", to_json(targets)},
          {"inputs", to_json(inputs)},
          {"skipped_scenes", r.skipped_scenes},
          {"conventions",
           "per view j: render_change = mean|R(p_j) - R(p_0)|, truth_change = mean|I_j - I_0| (pixels x channels, "
           "images in [0,1]); p_0 the first input's pose from the same source; sensitivity = mean render_change / "
           "mean truth_change (0: the decoder ignores the pose); psnr and grad_ratio of R(p_j) against I_j; inputs: "
           "the two context views rendered as targets"}};
}

void write_sensitivity_csv(const std::string& path, const SensitivityReport& r) {
  std::string text = "scene,frame,input,psnr,grad_ratio,render_change,truth_change\n";
  for (const auto& v : r.views)
    text += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.6f}\n", v.scene, v.frame, v.input ? 1 : 0, v.psnr,
                        v.grad_ratio, v.render_change, v.truth_change);
  io::write_file_atomic(path, text.data(), text.size());
}

}  // namespace uplvsm::study
