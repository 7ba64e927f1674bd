#include "uplvsm/train/optimizer.h"

#include <ATen/Parallel.h>

#include <cmath>

#include "uplvsm/kernels/bf16_simd.h"

// GCC 12's _mm512_sqrt_ps starts from _mm512_undefined_ps, which -Wmaybe-uninitialized misreads.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

namespace uplvsm::train {

ParamGroups split_param_groups(const torch::nn::Module& module) {
  ParamGroups g;
  for (const auto& item : module.named_parameters(true)) {
    if (!item.value().requires_grad()) continue;
    if (item.value().dim() > 1) {
      g.decay_names.push_back(item.key());
      g.decay.push_back(item.value());
    } else {
      g.no_decay_names.push_back(item.key());
      g.no_decay.push_back(item.value());
    }
  }
  return g;
}

namespace {
// What AdamW::step creates for a parameter it has no state for (step 0, zero moments, the parameter's layout).
void allocate_moments(torch::optim::AdamW& optimizer) {
  auto& states = optimizer.state();
  for (auto& group : optimizer.param_groups())
    for (auto& p : group.params()) {
      auto state = std::make_unique<torch::optim::AdamWParamState>();
      state->step(0);
      state->exp_avg(torch::zeros_like(p, torch::MemoryFormat::Preserve));
      state->exp_avg_sq(torch::zeros_like(p, torch::MemoryFormat::Preserve));
      states[state_key(states, p)] = std::move(state);
    }
}
}  // namespace

std::vector<torch::optim::OptimizerParamGroup> official_param_groups(const torch::nn::Module& module,
                                                                     const TrainingConfig& c) {
  auto groups = split_param_groups(module);
  auto options = [&](double wd) {
    return std::make_unique<torch::optim::AdamWOptions>(
        torch::optim::AdamWOptions(c.lr).betas({c.beta1, c.beta2}).eps(c.eps).weight_decay(wd));
  };
  std::vector<torch::optim::OptimizerParamGroup> param_groups;
  param_groups.emplace_back(groups.decay, options(c.weight_decay));
  param_groups.emplace_back(groups.no_decay, options(0.0));
  return param_groups;
}

std::unique_ptr<torch::optim::AdamW> make_optimizer(const torch::nn::Module& module, const TrainingConfig& c) {
  auto optimizer =
      std::make_unique<torch::optim::AdamW>(official_param_groups(module, c), torch::optim::AdamWOptions(c.lr));
  allocate_moments(*optimizer);
  return optimizer;
}

namespace {
// AdamW's per-step constants, rounded to fp32 as its tensor ops round their Scalar arguments.
struct AdamWConstants {
  float decay, beta1, one_minus_beta1, beta2, one_minus_beta2, sqrt_bias_correction2, eps, minus_step_size;
};

AdamWConstants adamw_constants(const torch::optim::AdamWOptions& o, int64_t step) {
  const auto [beta1, beta2] = o.betas();
  const double bias_correction1 = 1 - std::pow(beta1, static_cast<double>(step));
  const double bias_correction2 = 1 - std::pow(beta2, static_cast<double>(step));
  // No decay multiplies by 1, which is exact (AdamW::step skips the multiply).
  return {o.weight_decay() != 0 ? static_cast<float>(1 - o.lr() * o.weight_decay()) : 1.0f,
          static_cast<float>(beta1),
          static_cast<float>(1 - beta1),
          static_cast<float>(beta2),
          static_cast<float>(1 - beta2),
          static_cast<float>(std::sqrt(bias_correction2)),
          static_cast<float>(o.eps()),
          static_cast<float>(-(o.lr() / bias_correction1))};
}

// The element-wise body of AdamW::step, 16 lanes at a time: p.mul_(decay); m.mul_(b1).add_(g, 1 - b1) (ATen's add
// with alpha is one fused multiply-add); v.mul_(b2).addcmul_(g, g, 1 - b2) (one more: (1 - b2) g times g plus b2 v);
// denom = v.sqrt() / sqrt(bc2) + eps; p.addcdiv_(m, denom, -step_size) — every intermediate rounded to fp32 as there.
// No contraction: GCC would fuse the decayed weight's multiply into the final add, which ATen rounds in between.
UPLVSM_ROW_AVX512 __attribute__((optimize("fp-contract=off"))) void adamw_update_avx512(float* p, float* m, float* v,
                                                                                        const float* g, int64_t begin,
                                                                                        int64_t end,
                                                                                        const AdamWConstants& k) {
  const __m512 decay = _mm512_set1_ps(k.decay);
  const __m512 beta1 = _mm512_set1_ps(k.beta1), one_minus_beta1 = _mm512_set1_ps(k.one_minus_beta1);
  const __m512 beta2 = _mm512_set1_ps(k.beta2), one_minus_beta2 = _mm512_set1_ps(k.one_minus_beta2);
  const __m512 sqrt_bc2 = _mm512_set1_ps(k.sqrt_bias_correction2), eps = _mm512_set1_ps(k.eps);
  const __m512 minus_step_size = _mm512_set1_ps(k.minus_step_size);
  for (int64_t i = begin; i < end; i += 16) {
    const __mmask16 lanes = model::row_simd::tail_mask(end - i);
    const __m512 gi = _mm512_maskz_loadu_ps(lanes, g + i);
    const __m512 pi = _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, p + i), decay);
    const __m512 mi = _mm512_fmadd_ps(gi, one_minus_beta1, _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, m + i), beta1));
    const __m512 vi = _mm512_fmadd_ps(_mm512_mul_ps(one_minus_beta2, gi), gi,
                                      _mm512_mul_ps(_mm512_maskz_loadu_ps(lanes, v + i), beta2));
    const __m512 denom = _mm512_add_ps(_mm512_div_ps(_mm512_sqrt_ps(vi), sqrt_bc2), eps);
    _mm512_mask_storeu_ps(m + i, lanes, mi);
    _mm512_mask_storeu_ps(v + i, lanes, vi);
    _mm512_mask_storeu_ps(p + i, lanes, _mm512_add_ps(pi, _mm512_div_ps(_mm512_mul_ps(minus_step_size, mi), denom)));
  }
}

void adamw_update(float* p, float* m, float* v, const float* g, int64_t n, const AdamWConstants& k) {
  constexpr int64_t kGrain = 32768;  // small tensors (biases, norms) stay on the calling thread
  at::parallel_for(0, n, kGrain, [&](int64_t begin, int64_t end) { adamw_update_avx512(p, m, v, g, begin, end, k); });
}

bool fusable(const torch::Tensor& t) {
  return t.defined() && t.device().is_cpu() && t.scalar_type() == torch::kFloat32 && t.is_contiguous();
}

torch::optim::AdamWParamState* state_of(torch::optim::AdamW& optimizer, const torch::Tensor& p) {
  auto& states = optimizer.state();
  auto it = states.find(state_key(states, p));
  return it == states.end() ? nullptr : static_cast<torch::optim::AdamWParamState*>(it->second.get());
}

// Whether every parameter with a gradient, its gradient and its moments suit the one pass (checked before any
// update, so an optimiser is stepped wholly one way or the other).
bool one_pass_applies(torch::optim::AdamW& optimizer) {
  if (!model::row_simd::cpu_has_avx512()) return false;
  for (auto& group : optimizer.param_groups()) {
    if (static_cast<torch::optim::AdamWOptions&>(group.options()).amsgrad()) return false;
    for (auto& p : group.params()) {
      if (!p.grad().defined()) continue;
      const auto* state = state_of(optimizer, p);
      if (!state || !fusable(p) || !fusable(p.grad()) || !fusable(state->exp_avg()) || !fusable(state->exp_avg_sq()) ||
          state->exp_avg().numel() != p.numel() || state->exp_avg_sq().numel() != p.numel())
        return false;
    }
  }
  return true;
}
}  // namespace

void adamw_step(torch::optim::AdamW& optimizer) {
  if (!one_pass_applies(optimizer)) {
    optimizer.step();
    return;
  }
  torch::NoGradGuard no_grad;
  for (auto& group : optimizer.param_groups()) {
    const auto& options = static_cast<torch::optim::AdamWOptions&>(group.options());
    for (auto& p : group.params()) {
      if (!p.grad().defined()) continue;
      auto& state = *state_of(optimizer, p);
      state.step(state.step() + 1);
      adamw_update(p.data_ptr<float>(), state.exp_avg().data_ptr<float>(), state.exp_avg_sq().data_ptr<float>(),
                   p.grad().data_ptr<float>(), p.numel(), adamw_constants(options, state.step()));
      // As the in-place ops would: whoever caches a function of the weights (cast_once_linear) sees the change.
      for (const auto& t : {p, state.exp_avg(), state.exp_avg_sq()}) t.unsafeGetTensorImpl()->bump_version();
    }
  }
}

double lr_lambda(int64_t step, int64_t warmup, int64_t total) {
  if (step < warmup) return static_cast<double>(step) / static_cast<double>(std::max<int64_t>(1, warmup));
  double progress = static_cast<double>(step - warmup) / static_cast<double>(std::max<int64_t>(1, total - warmup));
  return std::max(0.0, 0.5 * (1.0 + std::cos(M_PI * progress)));
}

void set_learning_rate(torch::optim::Optimizer& opt, double lr) {
  for (auto& group : opt.param_groups()) static_cast<torch::optim::AdamWOptions&>(group.options()).lr(lr);
}

}  // namespace uplvsm::train
