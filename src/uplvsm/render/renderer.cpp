#include "uplvsm/render/renderer.h"

#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/io/image.h"
#include "uplvsm/io/video.h"
#include "uplvsm/model/encoded_scene.h"
#include "uplvsm/render/trajectory.h"

namespace uplvsm::render {

namespace fs = std::filesystem;

InterpolationVideo render_interpolation(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                        int64_t num_frames, int64_t chunk) {
  TORCH_CHECK(images.dim() == 4 && images.size(0) == 2 && images.size(1) == 3,
              "render_interpolation: expected two images [2, 3, H, W], got ", images.sizes());
  TORCH_CHECK(num_frames >= 2, "render_interpolation: need at least 2 frames");
  torch::NoGradGuard no_grad;
  net->eval();
  const auto scene = model::encode_scene(*net, images, fxfycxcy);
  auto poses = interpolate_poses(scene.input_poses, num_frames);
  auto intrinsics = interpolate_intrinsics(fxfycxcy.to(scene.latents.device()), num_frames);
  auto frames =
      model::render_latent_poses(*net, scene, poses.to(torch::kFloat32), intrinsics.to(torch::kFloat32), chunk);
  return {frames, poses.cpu(), scene.input_poses.cpu()};
}

torch::Tensor render_latent_path(model::UPLVSM& net, const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                 const torch::Tensor& poses, const torch::Tensor& intrinsics, int64_t chunk) {
  TORCH_CHECK(images.dim() == 4 && images.size(0) == 2 && images.size(1) == 3,
              "render_latent_path: expected two images [2, 3, H, W], got ", images.sizes());
  TORCH_CHECK(poses.dim() == 2 && poses.size(1) == 7 && intrinsics.dim() == 2 && intrinsics.size(0) == poses.size(0),
              "render_latent_path: expected poses [F, 7] and intrinsics [F, 4], got ", poses.sizes(), " and ",
              intrinsics.sizes());
  torch::NoGradGuard no_grad;
  net->eval();
  const auto scene = model::encode_scene(*net, images, fxfycxcy, /*estimate_input_poses=*/false);
  return model::render_latent_poses(*net, scene, poses.to(torch::kFloat32), intrinsics.to(torch::kFloat32), chunk);
}

torch::Device model_device(const torch::nn::Module& net) {
  auto params = net.parameters();
  return params.empty() ? torch::Device(torch::kCPU) : params.front().device();
}

torch::Tensor render_camera_path(model::NovelViewModel& net, const data::SceneViews& inputs, const torch::Tensor& poses,
                                 const torch::Tensor& fxfycxcy, int64_t chunk) {
  TORCH_CHECK(inputs.images.dim() == 4 && inputs.images.size(1) == 3,
              "render_camera_path: expected input images [v, 3, H, W], got ", inputs.images.sizes());
  TORCH_CHECK(poses.dim() == 2 && poses.size(1) == 7 && fxfycxcy.dim() == 2 && fxfycxcy.size(0) == poses.size(0),
              "render_camera_path: expected poses [F, 7] and intrinsics [F, 4], got ", poses.sizes(), " and ",
              fxfycxcy.sizes());
  torch::NoGradGuard no_grad;
  net->eval();
  const auto device = model_device(*net);
  const int64_t H = inputs.images.size(2), W = inputs.images.size(3);
  auto render_at = net->camera_control(model::batch_of_one(inputs, device));
  std::vector<torch::Tensor> out;
  for (int64_t s = 0; s < poses.size(0); s += chunk) {
    const int64_t n = std::min(chunk, poses.size(0) - s);
    auto k = fxfycxcy.slice(0, s, s + n).unsqueeze(0).to(device, torch::kFloat32);
    auto frames = render_at(poses.slice(0, s, s + n).unsqueeze(0), k, H, W);
    out.push_back(frames[0].to(torch::kFloat32).cpu());
  }
  return torch::cat(out);
}

torch::Tensor side_by_side(const torch::Tensor& inputs, const torch::Tensor& frames) {
  TORCH_CHECK(inputs.dim() == 4 && inputs.size(0) == 2 && frames.dim() == 4 && inputs.size(2) == frames.size(2),
              "side_by_side: expected inputs [2, 3, H, W] and frames [F, 3, H, W] of one height");
  auto left = torch::cat({inputs[0], inputs[1]}, 2).to(frames.device(), frames.scalar_type());  // [3, H, 2W]
  return torch::cat({left.unsqueeze(0).expand({frames.size(0), -1, -1, -1}), frames}, 3);
}

VideoFiles write_video(const std::string& dir, const std::string& name, const torch::Tensor& frames, double fps) {
  VideoFiles files;
  files.frames_dir = (fs::path(dir) / "frames").string();
  fs::create_directories(files.frames_dir);
  std::vector<torch::Tensor> u8;
  for (int64_t i = 0; i < frames.size(0); ++i) {
    u8.push_back(io::to_u8_hwc(frames[i].cpu()));
    io::write_png((fs::path(files.frames_dir) / fmt::format("frame_{:04d}.png", i)).string(), u8.back());
  }
  files.gif = (fs::path(dir) / (name + ".gif")).string();
  io::write_gif(files.gif, u8, fps);
  if (io::mp4_available()) {
    files.mp4 = (fs::path(dir) / (name + ".mp4")).string();
    io::write_mp4(files.mp4, u8, fps);
  } else {
    spdlog::warn("no MP4 encoder here (built without FFmpeg, or its FFmpeg lacks libx264 and mpeg4): wrote only {}",
                 files.gif);
  }
  return files;
}

}  // namespace uplvsm::render
