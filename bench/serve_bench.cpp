// Per-frame time of `uplvsm serve` at the viewer's resolution (the model's), as the server does it: with the
// latent cache (the session's scene latents kept: decoder + JPEG encode per frame) and without it (encoder,
// estimator, decoder and JPEG every frame), fp32 and bf16. Random weights (the time does not depend on them).
// Counters: wall ms per frame, and the process's CPU ms per frame (all threads), which a loaded machine inflates
// less than the wall time.
//   build/uplvsm_bench --benchmark_filter='ViewerFrame'
#include <benchmark/benchmark.h>

#include <torch/torch.h>

#include <chrono>
#include <ctime>
#include <string>

#include "bench_util.h"
#include "uplvsm/io/image.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/serve/viewer_model.h"

namespace {

using namespace uplvsm;

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

void BM_ViewerFrame(benchmark::State& state, const std::string& config_name) {
  const bool bf16 = state.range(0) != 0, cached = state.range(1) != 0;
  Config config = bench::bench_config(config_name);
  config.model.pose_mapper = true;  // the demo model has one; a 7x7 map per frame
  torch::manual_seed(0);
  model::UPLVSM net(config.model);
  serve::ViewerModel viewer(net.ptr(), config, bf16);
  const int64_t size = config.model.image_size;
  data::SceneViews views{torch::rand({2, 3, size, size}),
                         torch::tensor({0.9 * size, 0.9 * size, 0.5 * size, 0.5 * size}).expand({2, 4}).contiguous(),
                         torch::Tensor(),
                         {0, 1}};
  auto scene = viewer.encode(views, false);
  int64_t step = 0;
  auto frame = [&] {
    // A camera moving a little every frame, as a drag does.
    auto pose = torch::tensor({0.01 * (step++ % 50), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0}, torch::kFloat64).unsqueeze(0);
    if (!cached) scene = viewer.encode(views, false);
    return io::encode_jpeg(io::to_u8_hwc(viewer.render(scene, pose, serve::PoseSpace::Real)[0]), 90);
  };
  frame();  // warm-up
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) benchmark::DoNotOptimize(frame().data());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  state.counters["ms_per_frame"] = 1e3 * seconds / static_cast<double>(state.iterations());
  state.counters["cpu_ms_per_frame"] = 1e3 * (process_cpu_seconds() - cpu0) / static_cast<double>(state.iterations());
  state.counters["frames_per_s"] = static_cast<double>(state.iterations()) / seconds;
  state.SetLabel(std::string(bf16 ? "bf16" : "fp32") + (cached ? ", latents cached" : ", encode every frame"));
}
BENCHMARK_CAPTURE(BM_ViewerFrame, tiny, std::string("tiny"))
    ->ArgNames({"bf16", "cache"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_ViewerFrame, demo, std::string("demo"))
    ->ArgNames({"bf16", "cache"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_ViewerFrame, paper_x224, std::string("paper_x224"))
    ->ArgNames({"bf16", "cache"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

}  // namespace
