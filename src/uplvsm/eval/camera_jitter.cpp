#include "uplvsm/eval/camera_jitter.h"

#include <algorithm>
#include <filesystem>
#include <numeric>

#include <fmt/format.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/model/eval_mode.h"

namespace uplvsm::eval {

double temporal_jitter(const torch::Tensor& rendered, const torch::Tensor& truth) {
  TORCH_CHECK(rendered.dim() == 4 && rendered.sizes() == truth.sizes() && rendered.size(0) >= 2,
              "temporal_jitter: expected two [T >= 2, C, H, W] sequences of one shape, got ", rendered.sizes(), " and ",
              truth.sizes());
  auto r = rendered.to(torch::kFloat64), g = truth.to(torch::kFloat64);
  auto excess = (r.slice(0, 1) - r.slice(0, 0, -1)) - (g.slice(0, 1) - g.slice(0, 0, -1));  // [T-1, C, H, W]
  return 255.0 * excess.pow(2).mean({1, 2, 3}).sqrt().mean().item<double>();
}

namespace {

double frame_change(const torch::Tensor& truth) {
  auto g = truth.to(torch::kFloat64);
  return 255.0 * (g.slice(0, 1) - g.slice(0, 0, -1)).pow(2).mean({1, 2, 3}).sqrt().mean().item<double>();
}

// The scene's frames from its first context view on (at most max_frames), rendered at their real cameras.
std::pair<double, double> scene_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset, int64_t scene,
                                       const data::EvalEntry& entry, const data::PreprocessOptions& prep,
                                       const JitterOptions& opt) {
  const int64_t first = *std::min_element(entry.context.begin(), entry.context.end());
  const int64_t count = std::min(opt.max_frames, dataset.num_frames(scene) - first);
  std::vector<int64_t> path(static_cast<size_t>(count));
  std::iota(path.begin(), path.end(), first);
  auto inputs = model::batch_of_one(dataset.load_views(scene, entry.context, prep), opt.device);
  auto truth = dataset.load_views(scene, path, prep);
  torch::NoGradGuard no_grad;
  AutocastGuard amp(opt.device, opt.bf16);
  auto render = net->camera_control(inputs);
  auto poses = geometry::camera_control_poses(inputs.c2w, truth.c2w.unsqueeze(0).to(opt.device));
  std::vector<torch::Tensor> frames;
  for (int64_t s = 0; s < count; s += 8) {  // chunks bound the decoder's memory
    const int64_t n = std::min<int64_t>(8, count - s);
    frames.push_back(render(poses.narrow(1, s, n), truth.fxfycxcy.narrow(0, s, n).unsqueeze(0).to(opt.device),
                            truth.images.size(2), truth.images.size(3))[0]
                         .to(torch::kCPU, torch::kFloat32));
  }
  auto rendered = torch::cat(frames).clamp(0, 1);
  return {temporal_jitter(rendered, truth.images), frame_change(truth.images)};
}

}  // namespace

nlohmann::json JitterSummary::to_json() const {
  return {{"scenes", scenes}, {"frames", frames}, {"jitter", jitter}, {"truth_change", truth_change}};
}

JitterSummary measure_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                             const data::PreprocessOptions& prep, const JitterOptions& opt) {
  const auto index = opt.index_path.empty()
                         ? (std::filesystem::path(dataset.root()) / "evaluation_index.json").string()
                         : opt.index_path;
  auto entries = data::read_eval_index(index);
  model::EvalModeGuard mode(*net);
  JitterSummary out;
  const int64_t wanted = opt.max_scenes > 0 ? std::min<int64_t>(opt.max_scenes, entries.size()) : entries.size();
  ProgressBar bar("jitter", wanted, "scene");
  for (const auto& e : entries) {
    if (out.scenes >= wanted) break;
    const int64_t scene = dataset.find(e.key);
    if (scene < 0 || dataset.num_frames(scene) - *std::min_element(e.context.begin(), e.context.end()) < 2) continue;
    auto [jitter, change] = scene_jitter(net, dataset, scene, e, prep, opt);
    out.jitter += jitter;
    out.truth_change += change;
    out.frames += std::min(opt.max_frames, dataset.num_frames(scene) - *std::min_element(e.context.begin(),
                                                                                        e.context.end()));
    bar.update(++out.scenes);
  }
  bar.finish();
  if (out.scenes == 0) throw std::runtime_error("jitter: no scene of " + index + " is in " + dataset.root());
  out.jitter /= static_cast<double>(out.scenes);
  out.truth_change /= static_cast<double>(out.scenes);
  return out;
}

}  // namespace uplvsm::eval
