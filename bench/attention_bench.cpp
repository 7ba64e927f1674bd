// Attention micro-benchmark: softmax(q k^T / sqrt(d)) v over [1, 12 heads, L, 64] (the paper config's heads) for
// L = 256 .. 1536, fp32 and bf16, the fused kernel (model/flash_attention) against LibTorch's unfused matmul +
// softmax + matmul. Forward alone and forward + backward. Counters: TFLOP/s of the attention matmuls (forward
// 4 L^2 d per head, backward twice that; the fused backward's recomputation is not counted) and the fraction of
// the same-dtype matmul peak measured in this process. `AttentionDemo` is the demo model's encoder attention
// ([8 scenes, 4 heads, 544 tokens, d_head 32]), where the backward's small matmuls and element-wise passes weigh
// more. Run:
//   build/uplvsm_bench --benchmark_filter=Attention
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <chrono>

#include "bench_util.h"
#include "uplvsm/kernels/flash_attention.h"
#include "uplvsm/kernels/ops.h"
#include "uplvsm/model/transformer.h"

namespace {

using namespace uplvsm;

void run_attention(benchmark::State& state, int64_t B, int64_t heads, int64_t L, int64_t head_dim) {
  const bool bf16 = state.range(1) != 0, fused = state.range(2) != 0, backward = state.range(3) != 0;
  const auto dtype = bf16 ? torch::kBFloat16 : torch::kFloat32;
  kernels::set_attention_kernel(fused ? kernels::AttentionKernel::Fused : kernels::AttentionKernel::Unfused);
  if (fused && !kernels::fused_attention_applies(torch::kCPU, dtype, head_dim)) {
    state.SkipWithError("the fused kernel does not run on this CPU");
    return;
  }
  torch::manual_seed(0);
  auto make = [&] { return torch::randn({B, heads, L, head_dim}).to(dtype).requires_grad_(backward); };
  auto q = make(), k = make(), v = make();
  auto grad = torch::randn({B, heads, L, head_dim}).to(dtype);
  auto run = [&] {
    if (!backward) {
      torch::NoGradGuard no_grad;
      return kernels::attention(q, k, v);
    }
    auto o = kernels::attention(q, k, v);
    o.backward(grad);
    return q.grad();
  };
  run();  // warm-up: per-thread workspaces
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) benchmark::DoNotOptimize(run().data_ptr());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double forward_flops = 4.0 * B * heads * static_cast<double>(L) * L * head_dim;
  bench::set_flop_counters(state, forward_flops * (backward ? 3.0 : 1.0), seconds, bf16);
  state.SetLabel(std::string(bf16 ? "bf16" : "fp32") + (fused ? " fused" : " unfused") +
                 (backward ? " fwd+bwd" : " fwd"));
  kernels::set_attention_kernel(kernels::AttentionKernel::Fused);
}
void BM_Attention(benchmark::State& state) { run_attention(state, 1, 12, state.range(0), 64); }
void BM_AttentionDemo(benchmark::State& state) { run_attention(state, 8, 4, state.range(0), 32); }

BENCHMARK(BM_Attention)
    ->ArgNames({"L", "bf16", "fused", "bwd"})
    ->ArgsProduct({{256, 512, 1280, 1536}, {0, 1}, {1, 0}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_AttentionDemo)
    ->ArgNames({"L", "bf16", "fused", "bwd"})
    ->ArgsProduct({{544}, {0, 1}, {1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
