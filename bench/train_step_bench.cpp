// Training throughput: one optimiser step (forward, MSE loss, backward, AdamW) of the `tiny` and `paper_x224`
// configs at batch 1 with 2 input + 6 target views, and of `demo` as `make demo-model` trains it (batch 8, 2 input
// + 3 target views), in fp32 and bf16 autocast, with and without gradient checkpointing. Counters: steps/s
// (items_per_second), model TFLOP/s (3x the forward's matmul FLOPs, recomputation not counted) and MFU against the
// matmul peak this machine measured for the same dtype (BM_MatmulPeak). Peak memory is per process (getrusage), so
// measure one configuration per run, from the repository root:
//   build/uplvsm_bench --benchmark_filter='TrainStep/paper_x224/fp32/ckpt:1$'
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <chrono>
#include <string>

#include "bench_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/core/config.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/flops.h"
#include "uplvsm/train/optimizer.h"
#include "uplvsm/train/train_step.h"

namespace {

using namespace uplvsm;
using bench::bench_config, bench::matmul_flops_per_second, bench::peak_rss_gib;
constexpr int64_t kTrainInputViews = 2;

// The batch a benchmark trains at: the official per-GPU recipe (batch 1, 6 targets) or the demo model's.
struct TrainShape {
  int64_t batch = 1, target_views = 6;
};

void BM_MatmulPeak(benchmark::State& state) {
  const bool bf16 = state.range(0) != 0;
  const auto device = bench::bench_device();
  const auto options = torch::TensorOptions().dtype(bf16 ? torch::kBFloat16 : torch::kFloat32).device(device);
  auto a = torch::randn({2048, 768}, options), b = torch::randn({768, 3072}, options);
  for (auto _ : state) {
    benchmark::DoNotOptimize(torch::matmul(a, b).data_ptr());
    bench::synchronize(device);
  }
  state.counters["TFLOP/s"] = benchmark::Counter(
      2.0 * 2048 * 768 * 3072 * 1e-12 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.SetLabel(bf16 ? "bf16" : "fp32");
}
BENCHMARK(BM_MatmulPeak)->ArgName("bf16")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// LibTorch's AdamW::step, or the trainer's one-pass step (train::adamw_step) that gives the same numbers.
void step_adamw(torch::optim::AdamW& optimizer, bool one_pass) {
  if (one_pass)
    train::adamw_step(optimizer);
  else
    optimizer.step();
}

void run_train_step(benchmark::State& state, const std::string& config_name, TrainShape shape, bool bf16,
                    int64_t checkpoint_every, bool one_pass_adamw = true) {
  auto config = bench_config(config_name);
  config.training.batch_size = shape.batch;
  torch::manual_seed(0);
  model::UPLVSM net(config.model);
  const auto device = bench::bench_device();
  net->to(device);
  net->train();
  net->set_grad_checkpoint_every(checkpoint_every);
  auto optimizer = train::make_optimizer(*net, config.training);
  const auto params = train::trainable_parameters(*net);
  const int64_t S = config.model.image_size, v = kTrainInputViews + shape.target_views, B = shape.batch;
  auto images = torch::rand({B, v, 3, S, S}).to(device);
  auto fxfycxcy = torch::tensor({0.9 * S, 0.9 * S, 0.5 * S, 0.5 * S}).expand({B, v, 4}).contiguous().to(device);
  using torch::indexing::Slice;
  auto inputs = images.index({Slice(), Slice(0, kTrainInputViews)});
  auto targets = images.index({Slice(), Slice(kTrainInputViews)});
  auto in_k = fxfycxcy.index({Slice(), Slice(0, kTrainInputViews)});
  auto tgt_k = fxfycxcy.index({Slice(), Slice(kTrainInputViews)});
  auto step = [&] {
    train::release_gradients(params);  // as the trainer's step: no gradients held during the forward
    torch::Tensor loss;
    {
      AutocastGuard amp(device, bf16);
      auto out = net->forward(inputs, in_k, targets, tgt_k);
      loss = torch::mse_loss(out.render.to(torch::kFloat32), targets);
    }
    loss.backward();
    step_adamw(*optimizer, one_pass_adamw);
    return loss.item<double>();
  };
  step();  // warm-up: allocator, optimiser state
  // UPLVSM_PROFILE=DIR: one more step as a Chrome trace (not at the paper's size: the in-memory profiler of LibTorch
  // 1.13 ran out of 24 GiB there).
  if (config_name != "paper_x224")
    bench::maybe_profile("TrainStep_" + config_name + (bf16 ? "_bf16" : "_fp32") + (checkpoint_every ? "_ckpt" : ""),
                         step);
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) benchmark::DoNotOptimize(step());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double step_flops = 3.0 * train::forward_flops(config.model, B, kTrainInputViews, shape.target_views).total();
  state.SetItemsProcessed(state.iterations() * B);  // scenes/s
  state.counters["TFLOP/s"] =
      benchmark::Counter(step_flops * 1e-12 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  const double peak = matmul_flops_per_second(bf16);
  state.counters["peak_TFLOP/s"] = peak * 1e-12;
  state.counters["MFU"] = step_flops * static_cast<double>(state.iterations()) / seconds / peak;
  state.counters["model_TFLOP/step"] = step_flops * 1e-12;
  state.counters["peak_RSS_GiB"] = peak_rss_gib();
  state.SetLabel(std::string(bf16 ? "bf16" : "fp32") + (checkpoint_every ? " checkpointed" : ""));
}

void BM_TrainStep(benchmark::State& state, const std::string& config_name, TrainShape shape) {
  run_train_step(state, config_name, shape, state.range(0) != 0, state.range(1));
}
BENCHMARK_CAPTURE(BM_TrainStep, tiny, std::string("tiny"), TrainShape{})
    ->ArgNames({"bf16", "ckpt"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_TrainStep, paper_x224, std::string("paper_x224"), TrainShape{})
    ->ArgNames({"bf16", "ckpt"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(2);
BENCHMARK_CAPTURE(BM_TrainStep, demo, std::string("demo"), (TrainShape{8, 3}))
    ->ArgNames({"bf16", "ckpt"})
    ->ArgsProduct({{0, 1}, {0}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(5.0);
// The demo model at other batch sizes (issue 30: the batch that serves it best), bf16: scenes/s is the figure.
void BM_TrainStepDemoBatch(benchmark::State& state) { run_train_step(state, "demo", {state.range(0), 3}, true, 0); }
BENCHMARK(BM_TrainStepDemoBatch)
    ->ArgName("batch")
    ->Arg(2)
    ->Arg(4)
    ->Arg(16)
    ->Arg(32)
    ->Arg(64)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(5.0);

// The demo step (batch 8, bf16) with LibTorch's AdamW::step (fused:0) and with the trainer's one-pass step (fused:1),
// side by side in one process: what the one pass buys end to end.
void BM_TrainStepDemoAdamW(benchmark::State& state) {
  run_train_step(state, "demo", {8, 3}, true, 0, state.range(0) != 0);
}
BENCHMARK(BM_TrainStepDemoAdamW)
    ->ArgName("fused")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(5.0);

// The optimiser update alone on a model's parameters and realistic-size gradients: LibTorch's AdamW::step (fused:0,
// nine tensor ops per parameter) against train::adamw_step (fused:1, one pass), the same numbers.
void BM_AdamWStep(benchmark::State& state, const std::string& config_name) {
  auto config = bench_config(config_name);
  torch::manual_seed(0);
  model::UPLVSM net(config.model);
  auto optimizer = train::make_optimizer(*net, config.training);
  for (auto& p : train::trainable_parameters(*net)) p.mutable_grad() = torch::randn_like(p) * 1e-3;
  const bool fused = state.range(0) != 0;
  for (auto _ : state) step_adamw(*optimizer, fused);
  state.SetLabel(std::to_string(net->parameters().size()) + " tensors");
}
BENCHMARK_CAPTURE(BM_AdamWStep, demo, std::string("demo"))
    ->ArgName("fused")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_AdamWStep, paper_x224, std::string("paper_x224"))
    ->ArgName("fused")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(5);

}  // namespace
