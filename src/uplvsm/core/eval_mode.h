// A module in eval mode for a scope (evaluation, studies, calibration inside training): the mode it had comes back
// at the end of the scope, also when an exception leaves it.
#pragma once
#include <torch/torch.h>

namespace uplvsm {

class EvalModeGuard {
 public:
  explicit EvalModeGuard(torch::nn::Module& module) : module_(module), was_training_(module.is_training()) {
    module_.eval();
  }
  ~EvalModeGuard() { module_.train(was_training_); }
  EvalModeGuard(const EvalModeGuard&) = delete;
  EvalModeGuard& operator=(const EvalModeGuard&) = delete;

 private:
  torch::nn::Module& module_;
  bool was_training_;
};

}  // namespace uplvsm
