// Inference throughput of a model config at batch 1, as the official numbers are quoted: the UP-LVSM evaluation
// forward (2 input views + 3 target views; the estimator sees the targets) and the interpolation video (inputs
// encoded once, 8 frames decoded in chunks of 4), fp32 and bf16 autocast, no gradients. Counters: seconds per
// target view / per frame, model TFLOP/s and the fraction of the same-dtype matmul peak measured in this process.
//   build/uplvsm_bench --benchmark_filter='Inference/paper_x224'
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <chrono>
#include <string>

#include "bench_util.h"
#include "uplvsm/core/autocast.h"
#include "uplvsm/model/model_factory.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/render/renderer.h"
#include "uplvsm/train/flops.h"

namespace {

using namespace uplvsm;
constexpr int64_t kInputViews = 2, kTargetViews = 3, kFrames = 8;

// A randomly initialised model of a config in eval mode and one random scene of `views` views at its resolution, on
// the bench device ($UPLVSM_BENCH_DEVICE).
struct Setup {
  Config config;
  model::UPLVSM net{nullptr};
  torch::Tensor images, fxfycxcy;  // [1, v, 3, S, S], [1, v, 4]
};

Setup make_setup(const std::string& config_name, int64_t views) {
  Setup s{bench::bench_config(config_name)};
  torch::manual_seed(0);
  s.net = model::UPLVSM(s.config.model);
  s.net->eval();
  const int64_t size = s.config.model.image_size;
  s.images = torch::rand({1, views, 3, size, size});
  s.fxfycxcy = torch::tensor({0.9 * size, 0.9 * size, 0.5 * size, 0.5 * size}).expand({1, views, 4}).contiguous();
  const auto device = bench::bench_device();
  s.net->to(device);
  s.images = s.images.to(device);
  s.fxfycxcy = s.fxfycxcy.to(device);
  return s;
}

void BM_Inference(benchmark::State& state, const std::string& config_name) {
  const bool bf16 = state.range(0) != 0;
  auto setup = make_setup(config_name, kInputViews + kTargetViews);
  auto& net = setup.net;
  auto inputs = setup.images.narrow(1, 0, kInputViews), targets = setup.images.narrow(1, kInputViews, kTargetViews);
  auto in_k = setup.fxfycxcy.narrow(1, 0, kInputViews), tg_k = setup.fxfycxcy.narrow(1, kInputViews, kTargetViews);
  const auto device = bench::bench_device();
  auto run = [&] {
    torch::NoGradGuard no_grad;
    AutocastGuard amp(device, bf16);
    auto render = net->forward(inputs, in_k, targets, tg_k).render;
    bench::synchronize(device);
    return render;
  };
  run();  // warm-up
  bench::maybe_profile("Inference_" + config_name + (bf16 ? "_bf16" : "_fp32"), run);
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) benchmark::DoNotOptimize(run().data_ptr());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double iterations = static_cast<double>(state.iterations());
  bench::set_flop_counters(state, train::forward_flops(setup.config.model, 1, kInputViews, kTargetViews).total(),
                           seconds, bf16);
  state.counters["s_per_view"] = seconds / iterations / kTargetViews;
  state.counters["peak_RSS_GiB"] = bench::peak_rss_gib();
  state.SetLabel(bf16 ? "bf16" : "fp32");
}
BENCHMARK_CAPTURE(BM_Inference, tiny, std::string("tiny"))
    ->ArgName("bf16")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Inference, paper_x224, std::string("paper_x224"))
    ->ArgName("bf16")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(3);

void BM_RenderInterpolation(benchmark::State& state, const std::string& config_name) {
  const bool bf16 = state.range(0) != 0;
  auto setup = make_setup(config_name, kInputViews);
  const auto device = bench::bench_device();
  auto run = [&] {
    AutocastGuard amp(device, bf16);
    auto frames = render::render_interpolation(setup.net, setup.images[0], setup.fxfycxcy[0], kFrames).frames;
    bench::synchronize(device);
    return frames;
  };
  run();
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) benchmark::DoNotOptimize(run().data_ptr());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  state.counters["s_per_frame"] = seconds / static_cast<double>(state.iterations()) / kFrames;
  state.SetLabel(bf16 ? "bf16" : "fp32");
}
BENCHMARK_CAPTURE(BM_RenderInterpolation, tiny, std::string("tiny"))
    ->ArgName("bf16")
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_RenderInterpolation, paper_x224, std::string("paper_x224"))
    ->ArgName("bf16")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(2);

}  // namespace
