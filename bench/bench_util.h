// Helpers shared by the benchmarks: configs from configs/, the device the model benchmarks run on, the matmul peak
// of that device (the denominator of every "share of peak" figure, measured in the same process) and peak RSS.
#pragma once
#include <benchmark/benchmark.h>

#include <sys/resource.h>

#include <torch/torch.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <map>
#include <string>

#include <torch/csrc/autograd/profiler_legacy.h>
#include <torch/cuda.h>

#include "uplvsm/core/config.h"

namespace uplvsm::bench {

// Configs are read from $UPLVSM_CONFIG_DIR (default: configs/ under the working directory).
inline Config bench_config(const std::string& name) {
  const char* dir = std::getenv("UPLVSM_CONFIG_DIR");
  return load_config(std::string(dir ? dir : "configs") + "/" + name + ".json");
}

// The device of the model benchmarks (Inference, TrainStep, MatmulPeak): $UPLVSM_BENCH_DEVICE = cpu (default),
// cuda or cuda:N, so the same benchmarks time a GPU build.
inline torch::Device bench_device() {
  const char* name = std::getenv("UPLVSM_BENCH_DEVICE");
  return torch::Device(name && *name ? name : "cpu");
}

// Waits for the device's queued work: CUDA runs asynchronously, and a wall-clock time must cover the work.
inline void synchronize(torch::Device device) {
  if (device.is_cuda()) torch::cuda::synchronize(device.has_index() ? device.index() : -1);
}

// A matmul of the transformer's shape (2048 tokens x 768) @ (768 x 3072) on the bench device; FLOP/s of the best
// of 8 timed runs.
inline double matmul_flops_per_second(bool bf16) {
  static std::map<bool, double> cache;
  if (cache.count(bf16)) return cache[bf16];
  const auto device = bench_device();
  const auto options = torch::TensorOptions().dtype(bf16 ? torch::kBFloat16 : torch::kFloat32).device(device);
  auto a = torch::randn({2048, 768}, options), b = torch::randn({768, 3072}, options);
  const double flops = 2.0 * 2048 * 768 * 3072;
  double best = 0;
  for (int i = 0; i < 9; ++i) {
    synchronize(device);
    auto t0 = std::chrono::steady_clock::now();
    auto c = torch::matmul(a, b);
    synchronize(device);
    const double rate = flops / std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (i > 0) best = std::max(best, rate);  // the first run pays for handles and kernel selection
  }
  return cache[bf16] = best;
}

inline double peak_rss_gib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / (1024.0 * 1024.0);  // ru_maxrss is in KiB on Linux
}

// Rate counters of a benchmark that did `flops` per iteration: achieved TFLOP/s, the same-dtype matmul peak and
// the fraction of it reached.
inline void set_flop_counters(benchmark::State& state, double flops_per_iteration, double seconds, bool bf16) {
  const double achieved = flops_per_iteration * static_cast<double>(state.iterations()) / seconds;
  const double peak = matmul_flops_per_second(bf16);
  state.counters["TFLOP/s"] = achieved * 1e-12;
  state.counters["peak_TFLOP/s"] = peak * 1e-12;
  state.counters["of_peak"] = achieved / peak;
}

// With UPLVSM_PROFILE=DIR set, runs `fn` once more under LibTorch's (legacy, in-memory) profiler and writes
// DIR/<name>.trace.json (a Chrome trace: chrome://tracing or Perfetto) — where the time of one iteration goes, op by
// op.
template <typename Fn>
void maybe_profile(const std::string& name, Fn&& fn) {
  const char* dir = std::getenv("UPLVSM_PROFILE");
  if (!dir) return;
  std::string file = name;
  std::replace(file.begin(), file.end(), '/', '_');
  torch::autograd::profiler::RecordProfile guard(std::string(dir) + "/" + file + ".trace.json");
  fn();
}

}  // namespace uplvsm::bench
