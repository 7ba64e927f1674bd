// `uplvsm render`'s videos (render/videos.h).
#include "uplvsm/render/videos.h"

#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/render/trajectory.h"

namespace uplvsm::render {

namespace fs = std::filesystem;

namespace {

// The camera path of the video and its pixel intrinsics: real cameras in camera-control units, or latent poses
// (a camera-path file in "latent" units), or no poses for the latent interpolation (unposed inputs, or a model
// without camera control).
struct VideoPath {
  torch::Tensor poses, intrinsics;
  bool latent = false;
};

VideoPath camera_path(model::NovelViewModel& net, const data::SceneViews& views, bool posed, const VideoOptions& a) {
  const int64_t H = views.images.size(2), W = views.images.size(3);
  auto k0 = views.fxfycxcy[0].to(torch::kFloat64);
  auto repeat_k = [&](int64_t n) { return k0.unsqueeze(0).expand({n, 4}).contiguous(); };
  if (a.trajectory == "interpolate") {
    if (!posed || !net->has_camera_control()) return {};
    // SE(3) interpolation from the first input view (identity) to the second, in camera-control units.
    auto real = geometry::camera_control_poses(views.c2w.unsqueeze(0), views.c2w.unsqueeze(0))[0].to(torch::kFloat64);
    return {interpolate_poses(real.slice(0, 0, 2), a.frames),
            interpolate_intrinsics(views.fxfycxcy.to(torch::kFloat64).slice(0, 0, 2), a.frames)};
  }
  if (a.trajectory == "orbit" || a.trajectory == "spiral" || a.trajectory == "dolly") {
    PresetOptions o;
    o.focus_distance = a.focus;
    o.radius = a.radius;
    o.arc_degrees = a.arc;
    return {camera_path_preset(a.trajectory, a.frames, o), repeat_k(a.frames)};
  }
  auto path = read_camera_path(a.trajectory);
  const int64_t n = path.poses.size(0);
  if (!path.fxfycxcy_normalized.defined()) return {path.poses, repeat_k(n), path.latent};
  return {path.poses, geometry::intrinsics_to_pixels(path.fxfycxcy_normalized, H, W), path.latent};
}

// The frames stay in memory until the video is written (float32; with --side-by-side also a copy 3x as wide): a
// frame count that cannot fit is refused before rendering, with both numbers.
void check_video_fits(int64_t frames, const torch::Tensor& images, bool side_by_side) {
  const double bytes = 12.0 * static_cast<double>(frames * images.size(2) * images.size(3)) * (side_by_side ? 4 : 1);
  const auto available = available_memory(torch::kCPU);
  if (!available || bytes <= static_cast<double>(available->bytes)) return;
  throw std::runtime_error(
      fmt::format("render: {} frames of {}x{} need at least {} of memory, but only {} is available "
                  "({}); render fewer frames",
                  frames, images.size(3), images.size(2), format_bytes(bytes),
                  format_bytes(static_cast<double>(available->bytes)), available->source));
}

void render_one(model::NovelViewModel& net, const data::SceneViews& views, bool posed, const std::string& dir,
                const VideoOptions& a, nlohmann::json& listing, const std::string& name) {
  auto [poses, intrinsics, latent] = camera_path(net, views, posed, a);
  check_video_fits(poses.defined() ? poses.size(0) : a.frames, views.images, a.side_by_side);
  torch::Tensor frames, key_poses;
  {
    Bf16Autocast amp(model_device(*net), a.bf16);
    if (latent) {
      auto up = model::require_uplvsm(net, "render: a camera path in latent units");
      frames = render_latent_path(up, views.images, views.fxfycxcy, poses, intrinsics);
    } else if (poses.defined()) {
      auto inputs = views;
      if (!posed) inputs.c2w = torch::Tensor();  // photos: no cameras
      frames = render_camera_path(net, inputs, poses, intrinsics);
    } else {
      auto up = model::require_uplvsm(net, "render: the latent interpolation of inputs without cameras");
      auto video = render_interpolation(up, views.images, views.fxfycxcy, a.frames);
      frames = video.frames;
      key_poses = video.key_poses.to(torch::kFloat32).contiguous();
    }
  }
  frames = frames.to(torch::kFloat32);
  if (a.side_by_side) frames = side_by_side(views.images, frames);
  auto files = write_video(dir, "video", frames, a.fps);
  io::write_png((fs::path(dir) / "input_0.png").string(), io::to_u8_hwc(views.images[0]));
  io::write_png((fs::path(dir) / "input_1.png").string(), io::to_u8_hwc(views.images[1]));
  nlohmann::json entry = {{"name", name},
                          {"dir", dir},
                          {"mp4", files.mp4},
                          {"gif", files.gif},
                          {"frames", frames.size(0)},
                          {"width", frames.size(3)},
                          {"height", frames.size(2)},
                          {"trajectory", poses.defined() ? a.trajectory : "latent interpolation"}};
  if (key_poses.defined())
    entry["key_poses"] =
        std::vector<float>(key_poses.data_ptr<float>(), key_poses.data_ptr<float>() + key_poses.numel());
  listing.push_back(entry);
}

// One video per scene of the evaluation index (its context views), up to --scenes of those in the split.
void render_dataset_scenes(model::NovelViewModel& net, const VideoOptions& a, const data::PreprocessOptions& prep,
                           nlohmann::json& listing) {
  data::ChunkDataset dataset(a.data, a.split);
  auto index = a.index.empty() ? (fs::path(a.data) / "evaluation_index.json").string() : a.index;
  auto entries = data::read_eval_index(index);
  ProgressBar bar("render", std::min<int64_t>(a.scenes, static_cast<int64_t>(entries.size())), "scene");
  int64_t done = 0;
  for (const auto& e : entries) {
    if (done >= a.scenes) break;
    const int64_t scene = dataset.find(e.key);
    if (scene < 0) continue;
    render_one(net, dataset.load_views(scene, e.context, prep), true, (fs::path(a.out) / e.key).string(), a, listing,
               e.key);
    bar.update(++done);
  }
  bar.finish();
  if (done == 0) throw std::runtime_error("render: no scene of " + index + " is in " + a.data + "/" + a.split);
}

}  // namespace

nlohmann::json render_videos(model::NovelViewModel& net, const Config& config, const VideoOptions& options,
                             const std::vector<data::Photo>& photos) {
  const auto prep = data::square_preprocess_options(config);
  nlohmann::json listing = nlohmann::json::array();
  if (!photos.empty()) {
    render_one(net, data::photo_views(photos, prep), false, options.out, options, listing, "images");
    for (const auto& p : photos) listing.back()["inputs"].push_back(data::to_json(p.info, "--fov"));
  } else {
    render_dataset_scenes(net, options, prep, listing);
  }
  fs::create_directories(options.out);
  std::ofstream(fs::path(options.out) / "videos.json") << listing.dump(2) << "\n";
  return listing;
}

}  // namespace uplvsm::render
