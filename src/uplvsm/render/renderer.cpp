#include "uplvsm/render/renderer.h"

#include <filesystem>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/io/image.h"
#include "uplvsm/io/video.h"
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
  auto device = net->n_light_field_latent.device();
  auto inputs = images.unsqueeze(0).to(device);
  auto k = fxfycxcy.unsqueeze(0).to(device);
  const int64_t H = images.size(2), W = images.size(3);
  auto latents = net->encode_scene(inputs, k);
  auto key_poses = net->estimate_poses(inputs, latents)[0];  // [2, 7]
  auto poses = interpolate_poses(key_poses, num_frames);
  auto intrinsics = interpolate_intrinsics(k[0], num_frames);
  std::vector<torch::Tensor> out;
  for (int64_t s = 0; s < poses.size(0); s += chunk) {
    const int64_t n = std::min(chunk, poses.size(0) - s);
    out.push_back(net->render_views(latents, poses.slice(0, s, s + n).unsqueeze(0),
                                    intrinsics.slice(0, s, s + n).unsqueeze(0), H, W)[0]
                      .cpu());
  }
  return {torch::cat(out), poses.cpu(), key_poses.cpu()};
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
    spdlog::warn("no MP4 encoder in this FFmpeg build: wrote only {}", files.gif);
  }
  return files;
}

}  // namespace uplvsm::render
