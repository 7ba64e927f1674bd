#include "uplvsm/model/correspondence_displacement.h"

#include <cmath>

namespace uplvsm::model {

torch::Tensor patch_grid(int64_t n, const torch::TensorOptions& options) {
  const auto side = static_cast<int64_t>(std::llround(std::sqrt(static_cast<double>(n))));
  TORCH_CHECK(side * side == n, "patch_grid: ", n, " patches are not a square grid");
  auto centres = (torch::arange(side, options.dtype(torch::kFloat32)) + 0.5) / static_cast<double>(side) * 2 - 1;
  auto y = centres.view({side, 1}).expand({side, side}), x = centres.view({1, side}).expand({side, side});
  return torch::stack({x.reshape({n}), y.reshape({n})}, -1);
}

torch::Tensor correspondence_displacement(const torch::Tensor& queries, const torch::Tensor& keys,
                                          const torch::Tensor& grid) {
  TORCH_CHECK(queries.dim() == 3 && queries.sizes() == keys.sizes(),
              "correspondence_displacement: queries and keys must both be [N, n, c], got ", queries.sizes(), " and ",
              keys.sizes());
  const auto scale = 1.0 / std::sqrt(static_cast<double>(queries.size(2)));
  auto scores = torch::matmul(queries.to(torch::kFloat32), keys.to(torch::kFloat32).transpose(1, 2)) * scale;
  return torch::matmul(torch::softmax(scores, -1), grid) - grid;
}

CorrespondenceReadoutImpl::CorrespondenceReadoutImpl(int64_t d, int64_t d_head) {
  query = register_module("query", torch::nn::Linear(torch::nn::LinearOptions(d, d_head).bias(false)));
  key = register_module("key", torch::nn::Linear(torch::nn::LinearOptions(d, d_head).bias(false)));
  mlp = register_module("mlp", DinoMlp(4, d / 2, d));
  torch::NoGradGuard no_grad;
  query->weight.normal_(0.0, 0.02);
  key->weight.normal_(0.0, 0.02);
  mlp->fc1->bias.zero_();
  mlp->fc1->weight.normal_(0.0, 0.5);  // its 4 inputs are O(1): features of O(1), not of 0.02
  mlp->fc2->weight.zero_();
  mlp->fc2->bias.zero_();
}

torch::Tensor CorrespondenceReadoutImpl::forward(const torch::Tensor& target_tokens,
                                                 const torch::Tensor& view0_tokens) {
  auto grid = patch_grid(target_tokens.size(1), target_tokens.options());
  auto displacement = correspondence_displacement(query(target_tokens), key(view0_tokens), grid);  // [N, n, 2]
  return mlp(torch::cat({grid.expand_as(displacement), displacement}, -1)).mean(1);
}

}  // namespace uplvsm::model
