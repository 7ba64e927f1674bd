#include "uplvsm/eval/camera_jitter.h"

#include <algorithm>
#include <filesystem>
#include <numeric>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/geometry/quaternion.h"

namespace uplvsm::eval {

using torch::indexing::Slice;

torch::Tensor subdivide_path(const torch::Tensor& poses, int64_t s) {
  TORCH_CHECK(poses.dim() == 3 && poses.size(0) == 1 && poses.size(2) == 7 && poses.size(1) >= 1 && s >= 1,
              "subdivide_path: expected poses [1, n, 7] and subdivisions >= 1, got ", poses.sizes(), " and ", s);
  auto p = poses[0].to(torch::kFloat64);
  std::vector<torch::Tensor> out;
  for (int64_t i = 0; i + 1 < p.size(0); ++i)
    for (int64_t k = 0; k < s; ++k) {
      const double f = static_cast<double>(k) / static_cast<double>(s);
      auto t = p[i].slice(0, 0, 3) * (1 - f) + p[i + 1].slice(0, 0, 3) * f;
      out.push_back(torch::cat({t, geometry::quat_slerp(p[i].slice(0, 3), p[i + 1].slice(0, 3), f)}));
    }
  out.push_back(p[-1]);
  return torch::stack(out).unsqueeze(0).to(poses.dtype());
}

namespace {

int64_t first_context(const data::EvalEntry& e) { return *std::min_element(e.context.begin(), e.context.end()); }

struct PathJitter {
  double jitter = 0, speed = 0;
  int64_t renders = 0;
};

// The jitter of one scene's path, its renders' speed and how many renders it took.
PathJitter scene_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset, int64_t scene,
                        const data::EvalEntry& entry, const data::PreprocessOptions& prep, const JitterOptions& opt) {
  const int64_t count = std::min(opt.max_frames, dataset.num_frames(scene) - first_context(entry));
  std::vector<int64_t> frames(static_cast<size_t>(count));
  std::iota(frames.begin(), frames.end(), first_context(entry));
  auto inputs = model::batch_of_one(dataset.load_views(scene, entry.context, prep), opt.device);
  auto path_views = dataset.load_views(scene, frames, prep);
  torch::NoGradGuard no_grad;
  Bf16Autocast amp(opt.device, opt.bf16);
  auto render = net->camera_control(inputs);
  auto path = subdivide_path(geometry::camera_control_poses(inputs.c2w, path_views.c2w.unsqueeze(0).to(opt.device)),
                             opt.subdivisions);
  const int64_t n = path.size(1), H = path_views.images.size(2), W = path_views.images.size(3);
  std::vector<torch::Tensor> renders;
  for (int64_t s = 0; s < n; s += 8) {  // chunks bound the decoder's memory
    const int64_t m = std::min<int64_t>(8, n - s);
    auto k = path_views.fxfycxcy[0].view({1, 1, 4}).expand({1, m, 4}).to(opt.device);
    renders.push_back(render(path.narrow(1, s, m), k, H, W)[0].to(torch::kCPU, torch::kFloat32));
  }
  auto rendered = torch::cat(renders).clamp(0, 1);
  return {temporal_wobble(rendered), picture_speed(rendered), n};
}

}  // namespace

nlohmann::json JitterSummary::to_json() const {
  return {{"scenes", scenes},
          {"renders", renders},
          {"jitter", jitter},
          {"jitter_unit", "pixels per frame^2 (the rendered picture's change of motion)"},
          {"speed", speed}};
}

JitterSummary measure_jitter(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                             const data::PreprocessOptions& prep, const JitterOptions& opt) {
  const auto index = opt.index_path.empty() ? (std::filesystem::path(dataset.root()) / "evaluation_index.json").string()
                                            : opt.index_path;
  auto entries = data::read_eval_index(index);
  EvalModeGuard mode(*net);
  JitterSummary out;
  const int64_t wanted = opt.max_scenes > 0 ? std::min<int64_t>(opt.max_scenes, entries.size()) : entries.size();
  ProgressBar bar("jitter", wanted, "scene");
  for (const auto& e : entries) {
    if (out.scenes >= wanted) break;
    const int64_t scene = dataset.find(e.key);
    if (scene < 0 || dataset.num_frames(scene) - first_context(e) < 2) continue;
    const auto j = scene_jitter(net, dataset, scene, e, prep, opt);
    out.jitter += j.jitter;
    out.speed += j.speed;
    out.renders += j.renders;
    bar.update(++out.scenes);
  }
  bar.finish();
  if (out.scenes == 0) throw std::runtime_error("jitter: no scene of " + index + " is in " + dataset.root());
  out.jitter /= static_cast<double>(out.scenes);
  out.speed /= static_cast<double>(out.scenes);
  return out;
}

}  // namespace uplvsm::eval
