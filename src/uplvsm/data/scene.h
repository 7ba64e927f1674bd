// The two scene records of the data layer: a scene as stored in a pixelSplat chunk (RawScene: JPEG bytes and the
// 18-float camera rows) and a set of views ready for the model (SceneViews: float images, pixel intrinsics, c2w).
#pragma once
#include <torch/torch.h>

#include <cstdint>
#include <string>
#include <vector>

namespace uplvsm::data {

// One scene of a pixelSplat chunk (one dict of the torch.save'd list).
struct RawScene {
  std::string key;  // 16 lowercase hex characters for RealEstate10K
  std::string url;
  torch::Tensor timestamps;           // int64 [N], microseconds
  torch::Tensor cameras;              // float32 [N,18]: fx/W fy/H cx/W cy/H 0 0, then 3x4 world-to-camera row-major
  std::vector<torch::Tensor> images;  // N uint8 1-D tensors, each the complete bytes of one JPEG file
};

// The views of one scene after preprocessing (decode, resize, crop).
struct SceneViews {
  torch::Tensor images;         // float32 [V,3,H,W] in [0,1]
  torch::Tensor fxfycxcy;       // float32 [V,4], pixels of the HxW output
  torch::Tensor c2w;            // float32 [V,4,4], camera-to-world (OpenCV axes: x right, y down, z forward)
  std::vector<int64_t> frames;  // frame index of each view in its scene
  int64_t resized_frames = 0;   // of another size than the scene's frame 0, resized (FrameSizePolicy::Resize)
};

}  // namespace uplvsm::data
