#include "uplvsm/kernels/cast_once_linear.h"

#include <cstdlib>
#include <cstring>

#include <ATen/autocast_mode.h>

#include "uplvsm/core/autocast.h"
#include "uplvsm/kernels/bf16_linear.h"
#include "uplvsm/kernels/ops.h"

namespace uplvsm::kernels {

namespace {

bool same_storage(const c10::Storage& held, const torch::Tensor& t) {
  return t.defined() ? held.unsafeGetStorageImpl() == t.storage().unsafeGetStorageImpl() : !held;
}

int64_t version_of(const torch::Tensor& t) { return t.defined() ? static_cast<int64_t>(t._version()) : -1; }

// UPLVSM_LINEAR_CAST=per-call restores autocast's cast on every call (before/after comparisons in benchmarks).
bool cast_once_enabled() {
  static const bool enabled = [] {
    const char* env = std::getenv("UPLVSM_LINEAR_CAST");
    return !(env && std::strcmp(env, "per-call") == 0);
  }();
  return enabled;
}

}  // namespace

std::pair<torch::Tensor, torch::Tensor> LinearWeightCache::bf16_weights(const torch::Tensor& weight,
                                                                        const torch::Tensor& bias) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool current = weight_bf16_.defined() && same_storage(weight_storage_, weight) &&
                       same_storage(bias_storage_, bias) && weight_version_ == version_of(weight) &&
                       bias_version_ == version_of(bias);
  if (!current) {
    torch::NoGradGuard no_grad;
    weight_bf16_ = weight.to(torch::kBFloat16);
    bias_bf16_ = bias.defined() ? bias.to(torch::kBFloat16) : torch::Tensor();
    weight_storage_ = weight.storage();
    bias_storage_ = bias.defined() ? bias.storage() : c10::Storage();
    weight_version_ = version_of(weight);
    bias_version_ = version_of(bias);
  }
  return {weight_bf16_, bias_bf16_};
}

namespace {

// Training under CPU bf16 autocast: autocast's own casts (the weight's cached per autocast region, as aten::linear's
// autocast wrapper caches it), then bf16_linear for its faster weight gradient; nullopt where it does not serve.
std::optional<torch::Tensor> train_bf16(const torch::Tensor& input, const torch::Tensor& weight,
                                        const torch::Tensor& bias) {
  if (!torch::GradMode::is_enabled() || !input.device().is_cpu() || !autocast_active(input.device()) ||
      autocast_dtype(input.device()) != torch::kBFloat16 || !input.is_floating_point())
    return std::nullopt;
  const auto to_bf16 = [](const torch::Tensor& t) {
    return t.defined() ? at::autocast::cached_cast(torch::kBFloat16, t, c10::DeviceType::CPU) : t;
  };
  auto x = to_bf16(input), w = to_bf16(weight);
  if (!bf16_linear_applies(x, w)) return std::nullopt;
  return bf16_linear(x, w, to_bf16(bias));
}

}  // namespace

std::shared_ptr<LinearWeightCache> make_linear_weight_cache() { return std::make_shared<LinearWeightCache>(); }

torch::Tensor linear(const torch::Tensor& input, const torch::Tensor& weight, const torch::Tensor& bias,
                     LinearWeightCache& cache) {
  if (auto trained = train_bf16(input, weight, bias)) return *trained;
  const bool cast_once = cast_once_enabled() && !torch::GradMode::is_enabled() &&
                         weight.scalar_type() == torch::kFloat32 && autocast_active(weight.device());
  // ATen's linear, as PyTorch's nn.Linear: a bias folds into the matmul (addmm, also for 3-D inputs), where LibTorch
  // 1.13's C++ frontend (nn::LinearImpl) adds it in a separate pass — under autocast into a bf16 output via fp32.
  if (!cast_once) return torch::linear(input, weight, bias);
  auto [w, b] = cache.bf16_weights(weight, bias);
  return torch::linear(input, w, b);  // autocast casts the input; the weights are bf16 already
}

}  // namespace uplvsm::kernels
