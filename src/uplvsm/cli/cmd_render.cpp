// `uplvsm render`: a novel-view video between two input views — from dataset scenes (their evaluation context
// views) or from two image files of the user's own. The flags; render/videos.h renders.
#include <iostream>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/photo.h"
#include "uplvsm/render/trajectory.h"
#include "uplvsm/render/videos.h"

namespace uplvsm::cli {

namespace {

struct RenderArgs {
  CommonOptions common;
  ModelSource model;
  SceneSource source;
  render::VideoOptions video;
  Amp amp = Amp::None;
  std::vector<std::string> images;
  std::optional<double> fov;  // --images: given, it wins over the photos' EXIF focal length
};

void add_render_options(CLI::App* cmd, RenderArgs& a) {
  add_common_options(cmd, a.common);
  add_model_options(cmd, a.model);
  add_mapper_option(cmd, a.model);
  add_scene_source_options(cmd, a.source, "dataset root (pixelSplat chunks)",
                           "evaluation index JSON choosing the context views (default <data>/evaluation_index.json)");
  cmd->add_option("--scenes", a.video.scenes, "how many dataset scenes to render")->capture_default_str();
  cmd->add_option("--images", a.images, "two image files (JPEG/PNG) instead of dataset scenes")->expected(2);
  cmd->add_option_function<double>(
      "--fov", [&a](double fov) { a.fov = fov; },
      "horizontal field of view in degrees for --images (default: each photo's EXIF focal length, else 60)");
  cmd->add_option("--frames", a.video.frames, "frames of the video")
      ->check(CLI::Range(int64_t{2}, render::kMaxVideoFrames))
      ->capture_default_str();
  cmd->add_option("--fps", a.video.fps, "frames per second")->capture_default_str();
  cmd->add_option("--trajectory", a.video.trajectory,
                  "interpolate, orbit, spiral, dolly, or a camera-path JSON file ({\"frames\": [{\"pose\": [tx, ty, "
                  "tz, qx, qy, qz, qw]} or {\"c2w\": 4x4}, optional \"fxfycxcy\" normalised], first input view "
                  "canonical, OpenCV axes, translations in input baselines; or \"units\": \"latent\": latent poses "
                  "recorded in `uplvsm serve`)")
      ->capture_default_str();
  cmd->add_option("--focus", a.video.focus,
                  "presets: distance of the looked-at point in front of the first view (baselines)")
      ->capture_default_str();
  cmd->add_option("--radius", a.video.radius, "presets: spiral radius / dolly travel (baselines)")
      ->capture_default_str();
  cmd->add_option("--arc", a.video.arc, "orbit: total swing in degrees")->capture_default_str();
  cmd->add_flag("--side-by-side", a.video.side_by_side, "video frames show [input 0 | input 1 | render]");
  add_amp_option(cmd, a.amp, "model precision: none (fp32) or bf16 autocast");
  cmd->add_option("--out", a.video.out, "output directory")->required();
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
  auto options = a.video;
  options.bf16 = a.amp == Amp::Bf16;
  options.data = a.source.data, options.split = a.source.split, options.index = a.source.index;
  const auto listing = render::render_videos(net, config, options, photos);
  std::cout << fmt::format("rendered {} video(s) into {}\n", listing.size(), options.out);
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
