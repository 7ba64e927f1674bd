// Frame validation for the video writers (see video_frames.h).
#include "uplvsm/io/video_frames.h"

#include <cmath>
#include <stdexcept>

namespace uplvsm::io {

std::vector<torch::Tensor> checked_video_frames(const std::string& path, const std::vector<torch::Tensor>& frames,
                                                double fps) {
  if (frames.empty()) throw std::runtime_error("video '" + path + "': no frames to write");
  if (!(fps > 0.0) || !std::isfinite(fps))
    throw std::runtime_error("video '" + path + "': fps must be positive, got " + std::to_string(fps));
  std::vector<torch::Tensor> out;
  for (size_t i = 0; i < frames.size(); ++i) {
    const torch::Tensor& f = frames[i];
    std::string name = "video '" + path + "': frame " + std::to_string(i);
    if (!f.defined() || f.dim() != 3 || f.size(2) != 3 || f.size(0) < 1 || f.size(1) < 1)
      throw std::runtime_error(name + " must be a [H, W, 3] tensor");
    if (f.scalar_type() != torch::kUInt8) throw std::runtime_error(name + " must be uint8");
    if (i > 0 && (f.size(0) != out[0].size(0) || f.size(1) != out[0].size(1)))
      throw std::runtime_error(name + " is " + std::to_string(f.size(1)) + "x" + std::to_string(f.size(0)) +
                               " but frame 0 is " + std::to_string(out[0].size(1)) + "x" +
                               std::to_string(out[0].size(0)) + " (all frames must have the same size)");
    out.push_back(f.detach().to(torch::kCPU).contiguous());
  }
  return out;
}

}  // namespace uplvsm::io
