// QK-Norm micro-benchmark: the fused pass (model/qk_norm) against the unfused chain it replaces, forward alone and
// forward + backward, on the query view of a projection as QKNormAttention normalises it: the demo model's
// [8 scenes, 544 tokens, 4 heads, 32] and the paper's [3 views, 1280 tokens, 12 heads, 64]; fp32 and bf16
// (bf16 in, bf16 out: autocast's case). Run:
//   build/uplvsm_bench --benchmark_filter=QKNorm
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <optional>

#include "uplvsm/kernels/qk_norm.h"

namespace {

using namespace uplvsm;

void BM_QKNorm(benchmark::State& state) {
  const bool paper = state.range(0) != 0, bf16 = state.range(1) != 0, fused = state.range(2) != 0,
             backward = state.range(3) != 0;
  const int64_t B = paper ? 3 : 8, L = paper ? 1280 : 544, H = paper ? 12 : 4, D = paper ? 64 : 32;
  const auto dtype = bf16 ? torch::kBFloat16 : torch::kFloat32;
  torch::manual_seed(0);
  auto projection = torch::randn({B, L, 3 * H * D}).to(dtype).requires_grad_(backward);
  auto weight = torch::ones({D}).requires_grad_(backward);
  auto grad = torch::randn({B, L, H, D}).to(dtype);
  auto run = [&] {
    std::optional<torch::NoGradGuard> no_grad;
    if (!backward) no_grad.emplace();
    auto x = projection.chunk(3, -1)[0].view({B, L, H, D});
    auto y = fused ? kernels::qk_norm(x, weight, 1e-3, dtype) : kernels::qk_norm_unfused(x, weight, 1e-3, dtype);
    if (backward) y.backward(grad);
    return y;
  };
  run();
  for (auto _ : state) benchmark::DoNotOptimize(run().data_ptr());
  state.SetItemsProcessed(state.iterations() * B * L * H);
  state.SetLabel(std::string(paper ? "paper " : "demo ") + (bf16 ? "bf16" : "fp32") + (fused ? " fused" : " unfused") +
                 (backward ? " fwd+bwd" : " fwd"));
}
BENCHMARK(BM_QKNorm)
    ->ArgNames({"paper", "bf16", "fused", "bwd"})
    ->ArgsProduct({{0, 1}, {0, 1}, {1, 0}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
