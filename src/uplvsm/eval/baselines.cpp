#include "uplvsm/eval/baselines.h"

#include <cstdlib>
#include <stdexcept>
#include <string>

namespace uplvsm::eval {

int64_t nearest_input(const std::vector<int64_t>& input_frames, int64_t target) {
  if (input_frames.empty()) throw std::runtime_error("nearest_input: no input frames");
  int64_t best = 0;
  for (size_t i = 1; i < input_frames.size(); ++i)
    if (std::llabs(input_frames[i] - target) < std::llabs(input_frames[best] - target)) best = static_cast<int64_t>(i);
  return best;
}

torch::Tensor copy_nearest_input(const torch::Tensor& input_images,
                                 const std::vector<std::vector<int64_t>>& input_frames,
                                 const std::vector<std::vector<int64_t>>& target_frames) {
  if (input_images.dim() != 5)
    throw std::runtime_error("copy_nearest_input: input_images must be [b, vi, 3, H, W], got " +
                             c10::str(input_images.sizes()));
  const int64_t b = input_images.size(0), vi = input_images.size(1);
  if (static_cast<int64_t>(input_frames.size()) != b || static_cast<int64_t>(target_frames.size()) != b)
    throw std::runtime_error("copy_nearest_input: input_frames/target_frames need one entry per batch element (" +
                             std::to_string(b) + ")");
  const size_t vt = b > 0 ? target_frames[0].size() : 0;
  std::vector<int64_t> batch_idx, view_idx;
  for (int64_t i = 0; i < b; ++i) {
    if (static_cast<int64_t>(input_frames[i].size()) != vi)
      throw std::runtime_error("copy_nearest_input: input_frames[" + std::to_string(i) + "] has " +
                               std::to_string(input_frames[i].size()) + " frames, images have " + std::to_string(vi));
    if (target_frames[i].size() != vt)
      throw std::runtime_error("copy_nearest_input: target_frames[" + std::to_string(i) +
                               "] has another number of targets than target_frames[0]");
    for (int64_t t : target_frames[i]) {
      batch_idx.push_back(i);
      view_idx.push_back(nearest_input(input_frames[i], t));
    }
  }
  const auto device = input_images.device();
  auto bi = torch::tensor(batch_idx, torch::kInt64).to(device);
  auto vi_t = torch::tensor(view_idx, torch::kInt64).to(device);
  auto picked = input_images.index({bi, vi_t});  // [b * vt, 3, H, W]
  return picked.reshape(
      {b, static_cast<int64_t>(vt), input_images.size(2), input_images.size(3), input_images.size(4)});
}

torch::Tensor copy_nearest_direction(const torch::Tensor& input_images, const torch::Tensor& input_c2w,
                                     const torch::Tensor& target_c2w) {
  TORCH_CHECK(input_images.dim() == 5, "copy_nearest_direction: input_images must be [b, vi, 3, H, W], got ",
              input_images.sizes());
  const int64_t b = input_images.size(0), vi = input_images.size(1);
  TORCH_CHECK(input_c2w.dim() == 4 && input_c2w.size(0) == b && input_c2w.size(1) == vi && input_c2w.size(2) == 4 &&
                  input_c2w.size(3) == 4,
              "copy_nearest_direction: input_c2w must be [", b, ", ", vi, ", 4, 4], got ", input_c2w.sizes());
  TORCH_CHECK(target_c2w.dim() == 4 && target_c2w.size(0) == b && target_c2w.size(2) == 4 && target_c2w.size(3) == 4,
              "copy_nearest_direction: target_c2w must be [", b, ", vt, 4, 4], got ", target_c2w.sizes());
  using torch::indexing::Slice;
  auto forward = [](const torch::Tensor& c2w) {
    return c2w.index({Slice(), Slice(), Slice(0, 3), 2}).to(torch::kFloat64);
  };
  auto cosine = torch::einsum("btk,bik->bti", {forward(target_c2w), forward(input_c2w)});  // [b, vt, vi]
  // argmax returns the first maximum: ties go to the earlier input view.
  auto nearest = cosine.argmax(2).to(input_images.device());  // [b, vt]
  auto batch = torch::arange(b, nearest.options()).unsqueeze(1).expand_as(nearest);
  return input_images.index({batch, nearest});
}

torch::Tensor mean_colour(const torch::Tensor& target_images) {
  if (target_images.dim() < 3)
    throw std::runtime_error("mean_colour: expected [..., 3, H, W], got " + c10::str(target_images.sizes()));
  return target_images.mean({-2, -1}, /*keepdim=*/true).expand_as(target_images).contiguous();
}

}  // namespace uplvsm::eval
