#include "uplvsm/train/global_batch.h"

#include <stdexcept>

#include <fmt/format.h>

namespace uplvsm::train {

BatchPlan plan_batch(const TrainingConfig& t, int64_t ranks, const std::string& source) {
  if (ranks < 1) throw std::invalid_argument(fmt::format("{}: {} data-parallel ranks (need >= 1)", source, ranks));
  BatchPlan plan{t.batch_size, t.grad_accum_steps, ranks};
  if (t.global_batch_size <= 0) return plan;
  const int64_t per_step = t.batch_size * ranks;  // scenes in one micro-batch over all ranks
  if (t.global_batch_size % per_step != 0)
    throw std::runtime_error(fmt::format(
        "{}: training.global_batch_size = {} is not a multiple of training.batch_size ({}) x {} rank(s) = {}: "
        "choose a batch_size and a number of ranks whose product divides {}",
        source, t.global_batch_size, t.batch_size, ranks, per_step, t.global_batch_size));
  plan.accumulation = t.global_batch_size / per_step;
  if (t.grad_accum_steps != 1 && t.grad_accum_steps != plan.accumulation)
    throw std::runtime_error(fmt::format(
        "{}: training.grad_accum_steps = {} contradicts training.global_batch_size = {}, which needs {} on {} rank(s) "
        "at batch_size {}: leave grad_accum_steps at 1 (it is derived), or set global_batch_size to 0",
        source, t.grad_accum_steps, t.global_batch_size, plan.accumulation, ranks, t.batch_size));
  return plan;
}

}  // namespace uplvsm::train
