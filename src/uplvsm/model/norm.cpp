#include "uplvsm/model/norm.h"

#include "uplvsm/kernels/ops.h"

namespace uplvsm::model {

LayerNormImpl::LayerNormImpl(int64_t dim_, double eps_, bool with_bias) : dim(dim_), eps(eps_) {
  weight = register_parameter("weight", torch::ones({dim}));
  if (with_bias) bias = register_parameter("bias", torch::zeros({dim}));
}

torch::Tensor LayerNormImpl::forward(const torch::Tensor& x) { return torch::layer_norm(x, {dim}, weight, bias, eps); }

torch::Tensor LayerNormImpl::forward_into_linear(const torch::Tensor& x) {
  return kernels::layer_norm(x, weight, bias, eps, /*into_linear=*/true);
}

RMSNormImpl::RMSNormImpl(int64_t dim, double eps_) : eps(eps_) {
  weight = register_parameter("weight", torch::ones({dim}));
}

torch::Tensor RMSNormImpl::forward(const torch::Tensor& x) {
  return kernels::rms_norm(x, weight, eps, torch::promote_types(x.scalar_type(), weight.scalar_type()));
}

}  // namespace uplvsm::model
