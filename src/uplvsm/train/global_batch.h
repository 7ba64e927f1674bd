// The global batch of an optimiser step: scenes per micro-batch x micro-batches accumulated x processes (the
// official batch_size_per_gpu x grad_accum_steps x GPUs). The paper's recipe states it (128 at x224, 48 at x518 on
// the authors' 8 GPUs); one process, N ranks or N nodes reach the same number by accumulation derived here.
#pragma once
#include <cstdint>
#include <string>

#include "uplvsm/core/config.h"

namespace uplvsm::train {

struct BatchPlan {
  int64_t per_micro_batch = 1;  // training.batch_size: scenes in one forward on one process
  int64_t accumulation = 1;     // micro-batches whose gradients add up before each update, on every process
  int64_t ranks = 1;            // data-parallel processes
  int64_t global() const { return per_micro_batch * accumulation * ranks; }
};

// The plan of `training` on `ranks` processes. With training.global_batch_size set, the accumulation is
// global / (batch_size x ranks); throws naming `source`, the numbers and what would divide when it does not, or when
// training.grad_accum_steps says otherwise.
BatchPlan plan_batch(const TrainingConfig& training, int64_t ranks, const std::string& source);

}  // namespace uplvsm::train
