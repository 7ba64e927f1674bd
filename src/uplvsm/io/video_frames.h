// Frame checks shared by the video writers (GIF, MP4): a non-empty list of same-size uint8 [H, W, 3] frames and a
// positive fps, with errors that name the file and the offending frame.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

namespace uplvsm::io {

// The frames as contiguous CPU tensors; throws std::runtime_error naming `path` and the bad frame or fps.
std::vector<torch::Tensor> checked_video_frames(const std::string& path, const std::vector<torch::Tensor>& frames,
                                                double fps);

}  // namespace uplvsm::io
