#include "uplvsm/model/linear.h"

#include "uplvsm/kernels/ops.h"

namespace uplvsm::model {

LinearImpl::LinearImpl(const torch::nn::LinearOptions& options)
    : torch::nn::LinearImpl(options), cache_(kernels::make_linear_weight_cache()) {}

torch::Tensor LinearImpl::forward(const torch::Tensor& input) { return kernels::linear(input, weight, bias, *cache_); }

}  // namespace uplvsm::model
