// Weight-gradient micro-benchmark: dY^T X of a linear layer in bf16 training, our product (model/bf16_linear)
// against ATen's mm (oneDNN) on the demo model's four layer shapes (qkv 384 x 128, projection 128 x 128, MLP
// 512 x 128 and 128 x 512) over the rows of a batch-32 step (69632 tokens) and of a batch-8 one (17408). A training
// step's backward finds these operands out of cache (written long before, in the forward), so each iteration first
// streams through 64 MiB; that pass is outside the timed region. Run:
//   build/uplvsm_bench --benchmark_filter=WeightGradient
// (On a CPU with AMX-BF16 training takes ATen's; see kernels/bf16_linear.h.)
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <chrono>

#include "bench_util.h"
#include "uplvsm/kernels/bf16_linear.h"

namespace {

using namespace uplvsm;

void BM_WeightGradient(benchmark::State& state) {
  const int64_t K = state.range(0), O = state.range(1), I = state.range(2);
  const bool ours = state.range(3) != 0;
  auto input = torch::randn({K, I}).to(torch::kBFloat16);
  // Our product is measured wherever it can run, also where training takes ATen's (a CPU with AMX-BF16).
  const auto chosen = kernels::weight_gradient_path();
  kernels::set_weight_gradient_path(kernels::WeightGradientPath::Ours);
  const bool runs = kernels::bf16_linear_applies(input, torch::zeros({O, I}, torch::kBFloat16));
  kernels::set_weight_gradient_path(chosen);
  if (ours && !runs) {
    state.SkipWithError("our product does not run here (no AVX-512 BF16)");
    return;
  }
  torch::manual_seed(0);
  auto grad_output = torch::randn({K, O}).to(torch::kBFloat16);
  auto flush = torch::empty({64 << 20}, torch::kByte);
  auto run = [&] {
    return ours ? kernels::weight_gradient_bf16(grad_output, input) : torch::mm(grad_output.t(), input);
  };
  run();
  double seconds = 0;
  int64_t fill = 0;
  for (auto _ : state) {
    flush.fill_(++fill % 100);
    const auto start = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(run().data_ptr());
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    state.SetIterationTime(elapsed);
    seconds += elapsed;
  }
  bench::set_flop_counters(state, 2.0 * K * O * I, seconds, true);
  state.SetLabel(ours ? "ours" : "ATen mm");
}
BENCHMARK(BM_WeightGradient)
    ->ArgNames({"K", "O", "I", "ours"})
    ->ArgsProduct({{69632, 17408}, {384}, {128}, {1, 0}})
    ->ArgsProduct({{69632}, {128}, {128}, {1, 0}})
    ->ArgsProduct({{69632}, {512}, {128}, {1, 0}})
    ->ArgsProduct({{69632}, {128}, {512}, {1, 0}})
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

}  // namespace
