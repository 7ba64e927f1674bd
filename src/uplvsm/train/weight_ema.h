// training.ema_decay (not in the paper): an exponential moving average of the trainable weights (Polyak averaging, as
// TensorFlow's ExponentialMovingAverage with num_updates), which takes the step-to-step noise out of the weights a
// run hands on. While it is on, a checkpoint's model tensors are the average, so every reader (eval, export, render,
// --init) gets it unchanged, and the trained weights travel in the optimiser state as "online/<name>" for the resume.
#pragma once
#include <torch/torch.h>

#include <string>
#include <vector>

#include "uplvsm/model/state_dict.h"

namespace uplvsm::train {

inline constexpr const char* kOnlineWeightsKind = "online/";

struct WeightEma {
  double decay = 0;
  std::vector<std::string> names;
  std::vector<torch::Tensor> params;   // the module's trainable parameters, in `names` order
  std::vector<torch::Tensor> average;  // detached copies, fp32 like the parameters
};

// Starts the average at the module's current weights (a new run's, or the --init file's).
WeightEma make_weight_ema(const torch::nn::Module& module, double decay);

// The decay of the next update: min(decay, (1 + n) / (10 + n)), so a run from random weights is not held at them.
double ema_decay_at(double decay, int64_t updates);

// average <- d * average + (1 - d) * weights with d = ema_decay_at(decay, updates_so_far), after a parameter update
// (skipped updates leave it alone). The count lives in the training state (TrainState::ema_updates), for the resume.
void update_weight_ema(WeightEma& ema, int64_t updates_so_far);

// Exchanges the module's weights with the average (twice: back as they were). While swapped, `average` holds the
// trained weights.
void swap_weight_ema(WeightEma& ema);

// The swapped-out weights as named tensors "online/<name>" for a checkpoint's optimiser state (call while swapped).
model::NamedTensors online_weights_while_swapped(const WeightEma& ema);

// Resume: a checkpoint written with the average holds it as the model tensors (already loaded into the module) and the
// trained weights as "online/<name>". Moves the loaded weights into the average and the trained ones into the module.
// Returns false (nothing changed) when the checkpoint has no online weights. An online tensor whose name or shape
// matches no trainable parameter is an error naming `source`.
bool restore_online_weights(WeightEma& ema, const model::NamedTensors& optimizer_state, const std::string& source);

// RAII: the average in the module for a scope (periodic evaluation, checkpoint writing); nothing when ema is null.
class WeightEmaScope {
 public:
  explicit WeightEmaScope(WeightEma* ema) : ema_(ema) {
    if (ema_) swap_weight_ema(*ema_);
  }
  ~WeightEmaScope() {
    if (ema_) swap_weight_ema(*ema_);
  }
  WeightEmaScope(const WeightEmaScope&) = delete;
  WeightEmaScope& operator=(const WeightEmaScope&) = delete;

 private:
  WeightEma* ema_;
};

}  // namespace uplvsm::train
