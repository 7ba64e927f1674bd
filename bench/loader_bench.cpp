// Data loading throughput at the paper's resolution: RealEstate10K-sized JPEG frames (640x360) decoded, resized
// (PIL-exact Lanczos) and centre-cropped to 224², 8 views per scene (2 inputs + 6 targets). One batch built on the
// calling thread, and the threaded prefetching loader with 2 workers. Counters: scenes/s and decoded images/s.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/data/synthetic/room_scenes.h"

namespace {

using namespace uplvsm;

// Built-in scenes rendered once at 640x360 into a temporary folder.
const std::string& re10k_sized_dataset() {
  static std::string root;
  if (root.empty()) {
    root = (std::filesystem::temp_directory_path() / "uplvsm_loader_bench").string();
    if (!std::filesystem::exists(std::filesystem::path(root) / "train" / "index.json")) {
      data::RoomSceneOptions opt;
      opt.height = 360;
      opt.width = 640;
      opt.frames = 48;
      data::write_builtin_dataset(root, 8, 1, 5, opt);
    }
  }
  return root;
}

data::LoaderOptions paper_options(int threads) {
  data::LoaderOptions o;
  o.batch_size = 1;
  o.num_views = 8;
  o.num_input_views = 2;
  o.num_target_views = 6;
  o.min_frame_dist = 25;
  o.max_frame_dist = 192;
  o.preprocess = {224, 14, true};
  o.threads = threads;
  return o;
}

void set_rates(benchmark::State& state, int64_t scenes) {
  state.counters["scenes/s"] = benchmark::Counter(static_cast<double>(scenes), benchmark::Counter::kIsRate);
  state.counters["images/s"] = benchmark::Counter(static_cast<double>(scenes * 8), benchmark::Counter::kIsRate);
}

void BM_LoaderOneThread(benchmark::State& state) {
  data::ChunkDataset dataset(re10k_sized_dataset(), "train");
  const auto opt = paper_options(1);
  int64_t step = 0;
  for (auto _ : state) benchmark::DoNotOptimize(data::make_training_batch(dataset, opt, step++).images.data_ptr());
  set_rates(state, step);
}
BENCHMARK(BM_LoaderOneThread)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LoaderPrefetch(benchmark::State& state) {
  data::ChunkDataset dataset(re10k_sized_dataset(), "train");
  data::TrainingLoader loader(dataset, paper_options(static_cast<int>(state.range(0))), 0);
  int64_t scenes = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(loader.next().images.data_ptr());
    ++scenes;
  }
  set_rates(state, scenes);
}
BENCHMARK(BM_LoaderPrefetch)->ArgName("threads")->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
