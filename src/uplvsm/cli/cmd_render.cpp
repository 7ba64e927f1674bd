// `uplvsm render`: a novel-view video between two input views — from dataset scenes (their evaluation context
// views) or from two image files of the user's own.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/core/runtime.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/eval_index.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/checkpoint_io.h"
#include "uplvsm/render/renderer.h"

namespace uplvsm::cli {

namespace fs = std::filesystem;

namespace {

struct Args {
  CommonOptions common;
  ModelSource model;
  std::string data, split = "test", index, out, amp = "none";
  std::vector<std::string> images;
  int64_t scenes = 1, frames = 24;
  double fps = 12, fov = 60;
};

// A user's photo: pinhole camera with the principal point at the centre and the given horizontal field of view.
data::Views load_user_image(const std::string& path, double fov_deg, const data::PreprocessOptions& prep) {
  auto img = io::read_image(path);
  const double W = static_cast<double>(img.size(1)), H = static_cast<double>(img.size(0));
  const double fx_norm = 0.5 / std::tan(fov_deg * M_PI / 360.0);
  auto cam = torch::zeros({1, 18});
  cam[0][0] = fx_norm;
  cam[0][1] = fx_norm * W / H;  // square pixels
  cam[0][2] = 0.5;
  cam[0][3] = 0.5;
  for (int i = 0; i < 3; ++i) cam[0][6 + 5 * i] = 1.0;  // identity w2c: unused by the unposed model
  return data::preprocess({img}, cam, prep, path);
}

void render_one(model::UPLVSM& net, const data::Views& views, const std::string& dir, const Args& a,
                nlohmann::json& listing, const std::string& name) {
  render::InterpolationVideo video;
  {
    AutocastGuard amp(net->n_light_field_latent.device(), parse_amp(a.amp));
    video = render::render_interpolation(net, views.images, views.fxfycxcy, a.frames);
  }
  video.frames = video.frames.to(torch::kFloat32);
  auto files = render::write_video(dir, "video", video.frames, a.fps);
  io::write_png((fs::path(dir) / "input_0.png").string(), io::to_u8_hwc(views.images[0]));
  io::write_png((fs::path(dir) / "input_1.png").string(), io::to_u8_hwc(views.images[1]));
  auto poses = video.key_poses.to(torch::kFloat32).contiguous();
  listing.push_back({{"name", name}, {"dir", dir}, {"mp4", files.mp4}, {"gif", files.gif}, {"frames", video.frames.size(0)},
                     {"key_poses", std::vector<float>(poses.data_ptr<float>(), poses.data_ptr<float>() + poses.numel())}});
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "render", "Render a novel-view video between two input views: the Latent Plücker Learner estimates the inputs' "
                "latent poses, which are interpolated (linear translation, quaternion slerp) and decoded. Inputs "
                "come from --data scenes (their evaluation context views) or from --images A B (your photos).");
  auto a = std::make_shared<Args>();
  add_common_options(cmd, a->common);
  add_model_options(cmd, a->model);
  cmd->add_option("--data", a->data, "dataset root (pixelSplat chunks)");
  cmd->add_option("--split", a->split, "dataset split")->capture_default_str();
  cmd->add_option("--index", a->index, "evaluation index JSON choosing the context views (default <data>/evaluation_index.json)");
  cmd->add_option("--scenes", a->scenes, "how many dataset scenes to render")->capture_default_str();
  cmd->add_option("--images", a->images, "two image files (JPEG/PNG) instead of dataset scenes")->expected(2);
  cmd->add_option("--fov", a->fov, "horizontal field of view in degrees for --images")->capture_default_str();
  cmd->add_option("--frames", a->frames, "frames of the video")->check(CLI::Range(2, 100000))->capture_default_str();
  cmd->add_option("--fps", a->fps, "frames per second")->capture_default_str();
  cmd->add_option("--amp", a->amp, "model precision: none (fp32) or bf16 autocast")
      ->check(CLI::IsMember({"none", "bf16"}))
      ->capture_default_str();
  cmd->add_option("--out", a->out, "output directory")->required();
  cmd->callback([a] {
    apply_common_options(a->common);
    if (a->images.empty() == a->data.empty())
      throw std::runtime_error("render: give either --data (dataset scenes) or --images A B (two photos)");
    Config config;
    auto net = load_model(a->model, parse_device(a->common.device), &config);
    data::PreprocessOptions prep{static_cast<int>(config.model.image_size), static_cast<int>(config.model.patch_size),
                                 true};
    nlohmann::json listing = nlohmann::json::array();
    if (!a->images.empty()) {
      auto v0 = load_user_image(a->images[0], a->fov, prep), v1 = load_user_image(a->images[1], a->fov, prep);
      data::Views views{torch::cat({v0.images, v1.images}), torch::cat({v0.fxfycxcy, v1.fxfycxcy}),
                        torch::cat({v0.c2w, v1.c2w}), {0, 1}};
      render_one(net, views, a->out, *a, listing, "images");
    } else {
      data::ChunkDataset dataset(a->data, a->split);
      auto index = a->index.empty() ? (fs::path(a->data) / "evaluation_index.json").string() : a->index;
      auto entries = data::read_eval_index(index);
      ProgressBar bar("render", std::min<int64_t>(a->scenes, static_cast<int64_t>(entries.size())), "scene");
      int64_t done = 0;
      for (const auto& e : entries) {
        if (done >= a->scenes) break;
        const int64_t scene = dataset.find(e.key);
        if (scene < 0) continue;
        render_one(net, dataset.load_views(scene, e.context, prep), (fs::path(a->out) / e.key).string(), *a, listing,
                   e.key);
        bar.update(++done);
      }
      bar.finish();
      if (done == 0) throw std::runtime_error("render: no scene of " + index + " is in " + a->data + "/" + a->split);
    }
    fs::create_directories(a->out);
    std::ofstream(fs::path(a->out) / "videos.json") << listing.dump(2) << "\n";
    std::cout << fmt::format("rendered {} video(s) into {}\n", listing.size(), a->out);
  });
}

}  // namespace uplvsm::cli
