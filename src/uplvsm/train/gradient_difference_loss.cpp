#include "uplvsm/train/gradient_difference_loss.h"

#include "uplvsm/core/image_gradients.h"

namespace uplvsm::train {

torch::Tensor gradient_difference_loss(const torch::Tensor& pred, const torch::Tensor& target) {
  TORCH_CHECK(pred.sizes() == target.sizes() && pred.dim() >= 3,
              "gradient_difference_loss: expected pred and target of one shape [..., C, H, W], got ", pred.sizes(),
              " and ", target.sizes());
  TORCH_CHECK(pred.size(-2) >= 2 && pred.size(-1) >= 2, "gradient_difference_loss: images of ", pred.size(-2), "x",
              pred.size(-1), " have no pixel pairs along both axes");
  auto p = absolute_forward_differences(pred.to(torch::kFloat32));
  auto t = absolute_forward_differences(target.to(torch::kFloat32).detach());
  return (p - t).abs().mean();
}

}  // namespace uplvsm::train
