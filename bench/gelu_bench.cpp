// GELU micro-benchmark: the fused bf16 pass (model/gelu) against LibTorch's gelu on the MLP's hidden activations,
// forward alone and forward + backward: the demo model's encoder ([8 scenes, 544 tokens, 512]) and the paper's
// decoder over three target views ([3, 1280, 3072]). Run:
//   build/uplvsm_bench --benchmark_filter=Gelu
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <optional>

#include "uplvsm/kernels/gelu.h"

namespace {

using namespace uplvsm;

void BM_Gelu(benchmark::State& state) {
  const bool paper = state.range(0) != 0, fused = state.range(1) != 0, backward = state.range(2) != 0;
  const int64_t B = paper ? 3 : 8, L = paper ? 1280 : 544, H = paper ? 3072 : 512;
  if (fused && !kernels::gelu_fuses(torch::ones({1}, torch::kBFloat16))) {
    state.SkipWithError("the fused kernel does not run here (no AVX-512, or UPLVSM_GELU=aten)");
    return;
  }
  torch::manual_seed(0);
  auto x = torch::randn({B, L, H}).to(torch::kBFloat16).requires_grad_(backward);
  auto grad = torch::randn({B, L, H}).to(torch::kBFloat16);
  auto run = [&] {
    std::optional<torch::NoGradGuard> no_grad;
    if (!backward) no_grad.emplace();
    auto y = fused ? kernels::gelu(x) : torch::gelu(x);
    if (backward) y.backward(grad);
    return y;
  };
  run();
  for (auto _ : state) benchmark::DoNotOptimize(run().data_ptr());
  state.SetItemsProcessed(state.iterations() * B * L * H);
  state.SetLabel(std::string(paper ? "paper" : "demo") + (fused ? " fused" : " LibTorch") +
                 (backward ? " fwd+bwd" : " fwd"));
}
BENCHMARK(BM_Gelu)
    ->ArgNames({"paper", "fused", "bwd"})
    ->ArgsProduct({{0, 1}, {1, 0}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
