// `uplvsm render`: a novel-view video between two input views — from dataset scenes (their evaluation context
// views) or from two image files of the user's own.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/geometry/camera.h"
#include "uplvsm/geometry/camera_control.h"
#include "uplvsm/io/checkpoint_io.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/render/trajectory.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

struct RenderArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource source;
  std::string out, trajectory = "interpolate";
  Amp amp = Amp::None;
  double focus = 2.0, radius = 0.5, arc = 30.0;
  bool side_by_side = false;
  std::vector<std::string> images;
  int64_t scenes = 1, frames = 24;
  double fps = 12;
  std::optional<double> fov;  // --images: given, it wins over the photos' EXIF focal length
};

// The camera path of the video and its pixel intrinsics: real cameras in camera-control units, or latent poses
// (a camera-path file in "latent" units), or no poses for the latent interpolation (unposed inputs, or a model
// without camera control).
struct VideoPath {
  torch::Tensor poses, intrinsics;
  bool latent = false;
};

VideoPath camera_path(model::NovelViewModel& net, const data::SceneViews& views, bool posed, const RenderArgs& a) {
  const int64_t H = views.images.size(2), W = views.images.size(3);
  auto k0 = views.fxfycxcy[0].to(torch::kFloat64);
  auto repeat_k = [&](int64_t n) { return k0.unsqueeze(0).expand({n, 4}).contiguous(); };
  if (a.trajectory == "interpolate") {
    if (!posed || !net->has_camera_control()) return {};
    // SE(3) interpolation from the first input view (identity) to the second, in camera-control units.
    auto real = geometry::camera_control_poses(views.c2w.unsqueeze(0), views.c2w.unsqueeze(0))[0].to(torch::kFloat64);
    return {render::interpolate_poses(real.slice(0, 0, 2), a.frames),
            render::interpolate_intrinsics(views.fxfycxcy.to(torch::kFloat64).slice(0, 0, 2), a.frames)};
  }
  if (a.trajectory == "orbit" || a.trajectory == "spiral" || a.trajectory == "dolly") {
    render::PresetOptions o;
    o.focus_distance = a.focus;
    o.radius = a.radius;
    o.arc_degrees = a.arc;
    return {render::camera_path_preset(a.trajectory, a.frames, o), repeat_k(a.frames)};
  }
  auto path = render::read_camera_path(a.trajectory);
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
                const RenderArgs& a, nlohmann::json& listing, const std::string& name) {
  auto [poses, intrinsics, latent] = camera_path(net, views, posed, a);
  check_video_fits(poses.defined() ? poses.size(0) : a.frames, views.images, a.side_by_side);
  torch::Tensor frames, key_poses;
  {
    Bf16Autocast amp(render::model_device(*net), a.amp == Amp::Bf16);
    if (latent) {
      auto up = model::require_uplvsm(net, "render: a camera path in latent units");
      frames = render::render_latent_path(up, views.images, views.fxfycxcy, poses, intrinsics);
    } else if (poses.defined()) {
      auto inputs = views;
      if (!posed) inputs.c2w = torch::Tensor();  // photos: no cameras
      frames = render::render_camera_path(net, inputs, poses, intrinsics);
    } else {
      auto up = model::require_uplvsm(net, "render: the latent interpolation of inputs without cameras");
      auto video = render::render_interpolation(up, views.images, views.fxfycxcy, a.frames);
      frames = video.frames;
      key_poses = video.key_poses.to(torch::kFloat32).contiguous();
    }
  }
  frames = frames.to(torch::kFloat32);
  if (a.side_by_side) frames = render::side_by_side(views.images, frames);
  auto files = render::write_video(dir, "video", frames, a.fps);
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

void add_render_options(CLI::App* cmd, RenderArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
  add_mapper_option(cmd, a.model);
  add_scene_source_options(cmd, a.source, "dataset root (pixelSplat chunks)",
                           "evaluation index JSON choosing the context views (default <data>/evaluation_index.json)");
  cmd->add_option("--scenes", a.scenes, "how many dataset scenes to render")->capture_default_str();
  cmd->add_option("--images", a.images, "two image files (JPEG/PNG) instead of dataset scenes")->expected(2);
  cmd->add_option_function<double>(
      "--fov", [&a](double fov) { a.fov = fov; },
      "horizontal field of view in degrees for --images (default: each photo's EXIF focal length, else 60)");
  cmd->add_option("--frames", a.frames, "frames of the video")
      ->check(CLI::Range(int64_t{2}, render::kMaxVideoFrames))
      ->capture_default_str();
  cmd->add_option("--fps", a.fps, "frames per second")->capture_default_str();
  cmd->add_option("--trajectory", a.trajectory,
                  "interpolate, orbit, spiral, dolly, or a camera-path JSON file ({\"frames\": [{\"pose\": [tx, ty, "
                  "tz, qx, qy, qz, qw]} or {\"c2w\": 4x4}, optional \"fxfycxcy\" normalised], first input view "
                  "canonical, OpenCV axes, translations in input baselines; or \"units\": \"latent\": latent poses "
                  "recorded in `uplvsm serve`)")
      ->capture_default_str();
  cmd->add_option("--focus", a.focus, "presets: distance of the looked-at point in front of the first view (baselines)")
      ->capture_default_str();
  cmd->add_option("--radius", a.radius, "presets: spiral radius / dolly travel (baselines)")->capture_default_str();
  cmd->add_option("--arc", a.arc, "orbit: total swing in degrees")->capture_default_str();
  cmd->add_flag("--side-by-side", a.side_by_side, "video frames show [input 0 | input 1 | render]");
  add_amp_option(cmd, a.amp, "model precision: none (fp32) or bf16 autocast");
  cmd->add_option("--out", a.out, "output directory")->required();
}

// One video per scene of the evaluation index (its context views), up to --scenes of those in the split.
void render_dataset_scenes(model::NovelViewModel& net, const RenderArgs& a, const data::PreprocessOptions& prep,
                           nlohmann::json& listing) {
  const auto& src = a.source;
  data::ChunkDataset dataset(src.data, src.split);
  auto index = src.index.empty() ? (fs::path(src.data) / "evaluation_index.json").string() : src.index;
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
  if (done == 0) throw std::runtime_error("render: no scene of " + index + " is in " + src.data + "/" + src.split);
}

// The photos of --images, decoded and turned upright before the checkpoint is loaded (seconds and gigabytes for a
// large model): a mistyped path or a file that is not a photo is reported at once. Each photo's orientation and
// field of view go to the log.
std::vector<data::Photo> read_render_photos(const RenderArgs& a) {
  if (a.images.empty()) return {};
  auto photos = data::read_photos(a.images, a.fov);
  for (const auto& p : photos) spdlog::info("render: {}", data::describe_photo(p.info, "--fov"));
  return photos;
}

void run_render(const RenderArgs& a) {
  apply_common_options(a.common);
  log_kernel_paths();
  if (a.images.empty() == a.source.data.empty())
    throw std::runtime_error("render: give either --data (dataset scenes) or --images A B (two photos)");
  if (a.fov && a.images.empty()) spdlog::warn("render: --fov applies to --images only; the --data scenes keep theirs");
  const auto photos = read_render_photos(a);
  Config config;
  auto net = load_model_from_source(a.model, parse_device(a.common.device), &config);
  const auto prep = data::square_preprocess_options(config);
  nlohmann::json listing = nlohmann::json::array();
  if (!photos.empty()) {
    render_one(net, data::photo_views(photos, prep), false, a.out, a, listing, "images");
    for (const auto& p : photos) listing.back()["inputs"].push_back(data::to_json(p.info, "--fov"));
  } else {
    render_dataset_scenes(net, a, prep, listing);
  }
  fs::create_directories(a.out);
  std::ofstream(fs::path(a.out) / "videos.json") << listing.dump(2) << "\n";
  std::cout << fmt::format("rendered {} video(s) into {}\n", listing.size(), a.out);
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "render",
      "Render a novel-view video from two input views, from --data scenes (their evaluation context views) "
      "or --images A B (your photos). --trajectory interpolate: between the inputs - in latent pose space "
      "(the Latent Plücker Learner's poses of the inputs) for unposed photos, in SE(3) through the camera "
      "mapper or a posed variant when the inputs have cameras; orbit/spiral/dolly presets or a camera-path "
      "JSON: real cameras relative to the first input view (units: the input baseline), which need a "
      "camera mapper (`--mapper` from `uplvsm fit-mapper`, or `train --stage mapper`) or a posed variant.");
  auto a = std::make_shared<RenderArgs>();
  add_render_options(cmd, *a);
  cmd->callback([a] { run_render(*a); });
}

}  // namespace uplvsm::cli
