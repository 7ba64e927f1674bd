#include "uplvsm/train/optimizer.h"

#include <cmath>

#include "uplvsm/kernels/ops.h"

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
torch::optim::AdamWParamState* state_of(torch::optim::AdamW& optimizer, const torch::Tensor& p) {
  auto& states = optimizer.state();
  auto it = states.find(state_key(states, p));
  return it == states.end() ? nullptr : static_cast<torch::optim::AdamWParamState*>(it->second.get());
}

// Whether every parameter with a gradient, its gradient and its moments suit the one pass (checked before any
// update, so an optimiser is stepped wholly one way or the other).
bool one_pass_applies(torch::optim::AdamW& optimizer) {
  for (auto& group : optimizer.param_groups()) {
    if (static_cast<torch::optim::AdamWOptions&>(group.options()).amsgrad()) return false;
    for (auto& p : group.params()) {
      if (!p.grad().defined()) continue;
      const auto* state = state_of(optimizer, p);
      if (!state || !kernels::adamw_update_fuses(p, p.grad(), state->exp_avg(), state->exp_avg_sq())) return false;
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
      kernels::adamw_update(p, p.grad(), state.exp_avg(), state.exp_avg_sq(), state.step(), options);
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
