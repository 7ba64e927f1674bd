// Throughput of the evaluation metrics on 224x224 images (the paper's RE10K resolution): PSNR, SSIM, LPIPS (vgg and
// alex; random backbone weights, which cost the same as ImageNet ones) and the perceptual training loss with its
// backward pass. items_per_second = images per second. Run: build/uplvsm_bench --benchmark_filter=Metric
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include "uplvsm/eval/lpips.h"
#include "uplvsm/eval/metrics.h"
#include "uplvsm/train/perceptual_loss.h"

namespace {

using namespace uplvsm;
constexpr int64_t kSize = 224;

std::pair<torch::Tensor, torch::Tensor> image_pairs(int64_t n) {
  torch::manual_seed(0);
  auto gt = torch::rand({n, 3, kSize, kSize});
  return {(gt + 0.05 * torch::randn_like(gt)).clamp(0, 1), gt};
}

void BM_MetricPsnr(benchmark::State& state) {
  auto [pred, gt] = image_pairs(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(eval::psnr(pred, gt));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_MetricPsnr)->Arg(12)->Unit(benchmark::kMillisecond);

void BM_MetricSsim(benchmark::State& state) {
  auto [pred, gt] = image_pairs(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(eval::ssim(pred, gt));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_MetricSsim)->Arg(12)->Unit(benchmark::kMillisecond);

void BM_MetricLpips(benchmark::State& state, eval::LpipsNet net) {
  auto [pred, gt] = image_pairs(state.range(0));
  eval::Lpips lpips(net);
  lpips->eval();
  torch::NoGradGuard no_grad;
  for (auto _ : state) benchmark::DoNotOptimize(lpips->forward(pred, gt));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK_CAPTURE(BM_MetricLpips, vgg, eval::LpipsNet::Vgg)->Arg(10)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_MetricLpips, alex, eval::LpipsNet::Alex)->Arg(10)->Unit(benchmark::kMillisecond);

void BM_MetricPerceptualLossForwardBackward(benchmark::State& state) {
  auto [pred0, gt] = image_pairs(state.range(0));
  train::PerceptualLoss loss;
  for (auto _ : state) {
    auto pred = pred0.clone().requires_grad_(true);
    loss->forward(pred, gt).backward();
    benchmark::DoNotOptimize(pred.grad());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_MetricPerceptualLossForwardBackward)->Arg(6)->Unit(benchmark::kMillisecond);

}  // namespace
