#include "uplvsm/study/camera_paths.h"

#include <algorithm>
#include <filesystem>
#include <functional>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/eval_mode.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/eval/picture_motion.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/io/atomic_file.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::study {

namespace fs = std::filesystem;

torch::Tensor baseline_position(const torch::Tensor& poses, const torch::Tensor& input1_pose) {
  TORCH_CHECK(poses.dim() == 2 && poses.size(1) == 7 && input1_pose.numel() == 7,
              "baseline_position: expected poses [F, 7] and one pose [7], got ", poses.sizes(), " and ",
              input1_pose.sizes());
  auto t = poses.to(torch::kFloat64).narrow(1, 0, 3);
  auto d = input1_pose.reshape({7}).to(torch::kFloat64).narrow(0, 0, 3);
  return torch::matmul(t, d) / d.pow(2).sum().clamp_min(1e-12);
}

torch::Tensor camera_path_poses(const CameraPathsOptions& opt) {
  const auto& name = opt.trajectory;
  if (name == "orbit" || name == "spiral" || name == "dolly")
    return render::camera_path_preset(name, opt.frames, opt.preset).to(torch::kFloat32);
  const auto path = render::read_camera_path(name);
  if (path.latent)
    throw std::runtime_error("camera-paths: " + name +
                             " holds latent poses (\"units\": \"latent\"): the truth needs real cameras (baseline "
                             "units)");
  if (path.poses.size(0) < 3) throw std::runtime_error("camera-paths: " + name + " has fewer than 3 frames");
  return path.poses.to(torch::kFloat32);
}

namespace {

constexpr double kReproducedPsnr = 30.0;  // dB: a JPEG-q90 frame against its exact render is well above

data::SceneViews preprocess_render(const data::RoomRender& r, const data::PreprocessOptions& prep) {
  std::vector<torch::Tensor> frames;
  for (int64_t i = 0; i < r.images.size(0); ++i) frames.push_back(r.images[i]);
  return data::preprocess(frames, r.scene.cameras, prep, "camera-paths: the truth");
}

}  // namespace

ScenePath scene_path(const data::ChunkDataset& dataset, int64_t index, const data::EvalEntry& entry,
                     const data::PreprocessOptions& prep, const CameraPathsOptions& opt) {
  ScenePath s;
  s.key = entry.key;
  const auto url = dataset.scene(index).url;
  const auto seed = data::room_seed_from_url(url);
  if (!seed)
    throw std::runtime_error(
        fmt::format("camera-paths: scene {} of {} is not a built-in room (url '{}'): only "
                    "those can be rendered at any camera",
                    entry.key, dataset.root(), url));
  s.inputs = dataset.load_views(index, entry.context, prep);
  const auto inputs_again = preprocess_render(data::render_room_at(*seed, opt.room, s.inputs.c2w), prep);
  const double reproduced = eval::psnr(inputs_again.images, s.inputs.images).min().item<double>();
  if (reproduced < kReproducedPsnr)
    throw std::runtime_error(fmt::format(
        "camera-paths: scene {} of {} is not reproduced by the room options given ({:.1f} dB at its input frames): "
        "pass the config the dataset was made with (--room-config)",
        entry.key, dataset.root(), reproduced));
  s.poses = camera_path_poses(opt);
  auto c2w = s.inputs.c2w.unsqueeze(0);
  auto world = geometry::camera_control_to_world(c2w, s.poses.unsqueeze(0))[0];
  auto truth = preprocess_render(data::render_room_at(*seed, opt.room, world), prep);
  s.truth = truth.images;
  s.fxfycxcy = truth.fxfycxcy;
  s.position = baseline_position(s.poses, geometry::camera_control_poses(c2w, c2w)[0][1]);
  return s;
}

namespace {

// renderer(first, count) -> [count, 3, H, W] over the path in chunks that bound the decoder's memory.
torch::Tensor in_chunks(int64_t n, const std::function<torch::Tensor(int64_t, int64_t)>& renderer) {
  std::vector<torch::Tensor> out;
  for (int64_t s = 0; s < n; s += 8) out.push_back(renderer(s, std::min<int64_t>(8, n - s)).to(torch::kCPU));
  return torch::cat(out).to(torch::kFloat32).clamp(0, 1);
}

// The path rendered by each method: camera control, then (UP-LVSM) the estimator reading each true frame.
std::vector<std::pair<std::string, torch::Tensor>> render_path(model::NovelViewModel& net, const ScenePath& s,
                                                               const CameraPathsOptions& opt) {
  torch::NoGradGuard no_grad;
  Bf16Autocast amp(opt.device, opt.bf16);
  const int64_t n = s.poses.size(0), H = s.truth.size(2), W = s.truth.size(3);
  auto inputs = model::batch_of_one(s.inputs, opt.device);
  auto k = [&](int64_t first, int64_t m) { return s.fxfycxcy.narrow(0, first, m).unsqueeze(0).to(opt.device); };
  std::vector<std::pair<std::string, torch::Tensor>> out;
  auto control = net->camera_control(inputs);
  out.emplace_back("camera control", in_chunks(n, [&](int64_t first, int64_t m) {
                     return control(s.poses.narrow(0, first, m).unsqueeze(0).to(opt.device), k(first, m), H, W)[0];
                   }));
  auto* up = model::as_uplvsm(*net);
  if (up && opt.estimator) {
    auto latents = up->encode_scene(inputs.images, inputs.fxfycxcy);
    out.emplace_back("estimator reading the truth", in_chunks(n, [&](int64_t first, int64_t m) {
                       auto truth = s.truth.narrow(0, first, m).unsqueeze(0).to(opt.device);
                       return up->render_views(latents, up->estimate_poses(truth, latents), k(first, m), H, W)[0];
                     }));
  }
  return out;
}

double mean_where(const torch::Tensor& values, const torch::Tensor& mask) {
  return mask.any().item<bool>() ? values.index({mask}).mean().item<double>() : NAN;
}

}  // namespace

namespace {

// Each method's means over the frames inside and beyond the inputs' span, pooled over scenes; its wobble the mean of
// the scenes'.
void summarise(CameraPathsReport& report, const std::vector<std::string>& methods) {
  for (const auto& method : methods) {
    std::vector<double> psnr, ssim, wobble;
    std::vector<uint8_t> inside;
    for (const auto& f : report.frames)
      if (f.method == method) {
        psnr.push_back(f.psnr);
        ssim.push_back(f.ssim);
        inside.push_back(f.inside ? 1 : 0);
      }
    for (const auto& s : report.scene_scores)
      if (s.method == method) wobble.push_back(s.wobble);
    auto p = torch::tensor(psnr, torch::kFloat64), s = torch::tensor(ssim, torch::kFloat64);
    auto in = torch::tensor(inside, torch::kUInt8).to(torch::kBool);
    PathMethodScores m;
    m.method = method;
    m.psnr_inside = mean_where(p, in);
    m.psnr_beyond = mean_where(p, ~in);
    m.ssim_inside = mean_where(s, in);
    m.ssim_beyond = mean_where(s, ~in);
    m.wobble = torch::tensor(wobble, torch::kFloat64).mean().item<double>();
    report.methods.push_back(m);
  }
}

// Scores one scene's renders into the report: every frame, and each method's scene figures.
void score_scene(const ScenePath& path, const std::vector<std::pair<std::string, torch::Tensor>>& renders,
                 CameraPathsReport& report) {
  auto inside = (path.position >= 0) & (path.position <= 1);
  report.frames_inside += inside.sum().item<int64_t>();
  report.frames_beyond += inside.numel() - inside.sum().item<int64_t>();
  const auto truth_motion = eval::motion_change(path.truth);  // once per scene, for every method
  for (const auto& [method, frames] : renders) {
    auto psnr = eval::psnr(frames, path.truth).to(torch::kFloat64);
    auto ssim = eval::ssim(frames, path.truth).to(torch::kFloat64);
    for (int64_t f = 0; f < frames.size(0); ++f)
      report.frames.push_back({path.key, method, f, path.position[f].item<double>(), inside[f].item<bool>(),
                               psnr[f].item<double>(), ssim[f].item<double>()});
    report.scene_scores.push_back({path.key, method, psnr.mean().item<double>(), mean_where(psnr, inside),
                                   mean_where(psnr, ~inside), mean_where(ssim, inside), mean_where(ssim, ~inside),
                                   eval::temporal_wobble(frames, truth_motion)});
  }
}

}  // namespace

CameraPathsReport run_camera_paths(model::NovelViewModel& net, const data::ChunkDataset& dataset,
                                   const data::PreprocessOptions& prep, const CameraPathsOptions& opt) {
  const auto index =
      opt.index_path.empty() ? (fs::path(dataset.root()) / "evaluation_index.json").string() : opt.index_path;
  const auto entries = data::read_eval_index(index);
  EvalModeGuard mode(*net);
  CameraPathsReport report;
  std::vector<std::string> methods;
  const int64_t wanted = opt.max_scenes > 0 ? std::min<int64_t>(opt.max_scenes, entries.size()) : entries.size();
  ProgressBar bar("camera paths", wanted, "scene");
  for (const auto& e : entries) {
    if (report.scenes >= wanted) break;
    const int64_t scene = dataset.find(e.key);
    if (scene < 0) continue;
    const auto path = scene_path(dataset, scene, e, prep, opt);
    const auto renders = render_path(net, path, opt);
    if (methods.empty())
      for (const auto& r : renders) methods.push_back(r.first);
    score_scene(path, renders, report);
    bar.update(++report.scenes);
  }
  bar.finish();
  if (report.scenes == 0) throw std::runtime_error("camera-paths: no scene of " + index + " is in " + dataset.root());
  summarise(report, methods);
  return report;
}

nlohmann::json CameraPathsReport::to_json() const {
  auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  nlohmann::json methods_json = nlohmann::json::array();
  for (const auto& m : methods)
    methods_json.push_back({{"method", m.method},
                            {"psnr_inside", number(m.psnr_inside)},
                            {"psnr_beyond", number(m.psnr_beyond)},
                            {"ssim_inside", number(m.ssim_inside)},
                            {"ssim_beyond", number(m.ssim_beyond)},
                            {"wobble", m.wobble}});
  return {{"scenes", scenes},
          {"frames_inside", frames_inside},
          {"frames_beyond", frames_beyond},
          {"wobble_unit", "pixels per frame^2, relative to the truth's motion"},
          {"methods", methods_json}};
}

void write_camera_paths(const CameraPathsReport& report, const std::string& out_dir) {
  const fs::path out(out_dir);
  fs::create_directories(out);
  const auto json = report.to_json().dump(2) + "\n";
  io::write_file_atomic((out / "camera_paths.json").string(), json.data(), json.size());
  std::ostringstream csv;
  csv << "scene,method,frame,position,inside,psnr,ssim\n";
  for (const auto& f : report.frames)
    csv << fmt::format("{},{},{},{:.4f},{},{:.4f},{:.4f}\n", f.scene, f.method, f.frame, f.position, f.inside ? 1 : 0,
                       f.psnr, f.ssim);
  const auto text = csv.str();
  io::write_file_atomic((out / "camera_paths.csv").string(), text.data(), text.size());
  auto number = [](double v) { return std::isfinite(v) ? fmt::format("{:.6f}", v) : std::string(); };
  std::ostringstream scenes;
  scenes << "scene,method,psnr,psnr_inside,psnr_beyond,ssim_inside,ssim_beyond,wobble\n";
  for (const auto& s : report.scene_scores)
    scenes << fmt::format("{},{},{},{},{},{},{},{}\n", s.scene, s.method, number(s.psnr), number(s.psnr_inside),
                          number(s.psnr_beyond), number(s.ssim_inside), number(s.ssim_beyond), number(s.wobble));
  const auto scenes_text = scenes.str();
  io::write_file_atomic((out / "camera_paths_scenes.csv").string(), scenes_text.data(), scenes_text.size());
}

}  // namespace uplvsm::study
