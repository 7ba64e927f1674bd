#include "uplvsm/train/weight_ema.h"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "uplvsm/train/checkpoint.h"

namespace uplvsm::train {

WeightEma make_weight_ema(const torch::nn::Module& module, double decay) {
  torch::NoGradGuard no_grad;
  WeightEma ema;
  ema.decay = decay;
  for (const auto& [name, param] : named_trainable_parameters(module)) {  // frozen weights are their own average
    ema.names.push_back(name);
    ema.params.push_back(param);
    ema.average.push_back(param.detach().clone());
  }
  return ema;
}

double ema_decay_at(double decay, int64_t updates) {
  return std::min(decay, (1.0 + static_cast<double>(updates)) / (10.0 + static_cast<double>(updates)));
}

void update_weight_ema(WeightEma& ema, int64_t updates_so_far) {
  torch::NoGradGuard no_grad;
  const double d = ema_decay_at(ema.decay, updates_so_far);
  // lerp_(w, 1 - d) is d * average + (1 - d) * w in one pass, without a temporary.
  for (size_t i = 0; i < ema.params.size(); ++i) ema.average[i].lerp_(ema.params[i].detach(), 1.0 - d);
}

void swap_weight_ema(WeightEma& ema) {
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < ema.params.size(); ++i) {
    auto weights = ema.params[i].detach().clone();
    ema.params[i].detach().copy_(ema.average[i]);
    ema.average[i].copy_(weights);
  }
}

model::NamedTensors online_weights_while_swapped(const WeightEma& ema) {
  model::NamedTensors out;
  for (size_t i = 0; i < ema.names.size(); ++i)
    out[std::string(kOnlineWeightsKind) + ema.names[i]] = ema.average[i].detach().cpu();
  return out;
}

bool restore_online_weights(WeightEma& ema, const model::NamedTensors& optimizer_state, const std::string& source) {
  const std::string kind = kOnlineWeightsKind;
  size_t found = 0;
  for (const auto& [key, tensor] : optimizer_state) found += key.rfind(kind, 0) == 0;
  if (found == 0) return false;
  if (found != ema.names.size())
    throw std::runtime_error(fmt::format("{}: {} trained-weight tensors ({}*) for a model of {} trainable parameters",
                                         source, found, kind, ema.names.size()));
  torch::NoGradGuard no_grad;
  for (size_t i = 0; i < ema.names.size(); ++i) {
    auto it = optimizer_state.find(kind + ema.names[i]);
    if (it == optimizer_state.end())
      throw std::runtime_error(fmt::format("{}: no trained weights {}{}", source, kind, ema.names[i]));
    if (it->second.sizes() != ema.params[i].sizes())
      throw std::runtime_error(fmt::format("{}: trained weights {}{} have shape [{}] but the parameter is [{}]", source,
                                           kind, ema.names[i], fmt::join(it->second.sizes(), ","),
                                           fmt::join(ema.params[i].sizes(), ",")));
    ema.average[i].copy_(ema.params[i].detach());
    ema.params[i].detach().copy_(it->second);
  }
  return true;
}

}  // namespace uplvsm::train
