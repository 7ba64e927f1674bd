// `uplvsm dataset`: dataset tools. `convert` moves a split between pixelSplat chunks and the LVSM layout the
// official UP-LVSM trains on (lossless both ways); `stats` reports what a split holds and what the loader will skip.
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/progress.h"
#include "uplvsm/data/dataset_stats.h"
#include "uplvsm/data/lvsm_layout.h"
#include "uplvsm/data/subset.h"
#include "uplvsm/io/atomic_file.h"

namespace uplvsm::cli {

namespace {

void add_convert(CLI::App& dataset) {
  auto* cmd = dataset.add_subcommand(
      "convert",
      "Convert one split between pixelSplat chunks (<split>/*.torch + index.json) and the LVSM layout "
      "(<split>/images/<scene>/NNNNN.png, <split>/metadata/<scene>.json, <split>/full_list.txt). "
      "chunks -> lvsm decodes each JPEG and writes PNG (as the official process_data.py); lvsm -> chunks "
      "stores the PNG bytes unchanged, so both directions keep the pixels.");
  struct Args {
    std::string from, input, output;
    int64_t scenes_per_chunk = 100;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--from", a->from, "layout of --input: chunks or lvsm")
      ->required()
      ->check(CLI::IsMember({"chunks", "lvsm"}));
  cmd->add_option("--input", a->input, "split folder to read (e.g. re10k/train)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--output", a->output, "split folder to write")->required();
  cmd->add_option("--scenes-per-chunk", a->scenes_per_chunk, "lvsm -> chunks: scenes per .torch file")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->callback([a] {
    if (std::filesystem::exists(a->output) && !std::filesystem::is_empty(a->output))
      throw std::runtime_error("dataset convert: --output " + a->output + " exists and is not empty");
    std::unique_ptr<ProgressBar> bar;
    auto progress = [&](int64_t done, int64_t total) {
      if (!bar) bar = std::make_unique<ProgressBar>("convert", total, "scene");
      bar->update(done);
    };
    auto r = a->from == "chunks" ? data::chunks_to_lvsm(a->input, a->output, progress)
                                 : data::lvsm_to_chunks(a->input, a->output, a->scenes_per_chunk, progress);
    if (bar) bar->finish();
    std::cout << fmt::format("converted {} scenes ({} frames) into {} ({} {})\n", r.scenes, r.frames, a->output,
                             r.files, a->from == "chunks" ? "metadata files + full_list.txt" : "chunks + index.json");
  });
}

void add_stats(CLI::App& dataset) {
  auto* cmd = dataset.add_subcommand(
      "stats",
      "Scenes, chunks, frames per scene, image sizes and the frames the loader will skip (another size than "
      "frame 0) or refuse (non-finite cameras) in one split; reads headers only");
  struct Args {
    std::string data, split = "train", out;
    int64_t min_frames = 8;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--data", a->data, "dataset root (pixelSplat chunks or LVSM layout)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a->split, "split")->capture_default_str();
  cmd->add_option("--min-frames", a->min_frames, "count scenes with fewer frames (training needs num_views)")
      ->capture_default_str();
  cmd->add_option("--out", a->out, "also write the statistics as JSON here");
  cmd->callback([a] {
    std::unique_ptr<ProgressBar> bar;
    auto st = data::dataset_stats(a->data, a->split, a->min_frames, [&](int64_t done, int64_t total) {
      if (!bar) bar = std::make_unique<ProgressBar>("stats", total, "scene");
      bar->update(done);
    });
    if (bar) bar->finish();
    const auto j = data::to_json(st);
    std::cout << j.dump(2) << "\n";
    if (!a->out.empty()) {
      const auto text = j.dump(2) + "\n";
      io::write_file_atomic(a->out, text.data(), text.size());
    }
  });
}

void add_subset(CLI::App& dataset) {
  auto* cmd = dataset.add_subcommand(
      "subset",
      "Select a training subset and write its manifest for `uplvsm train --subset`: the paper's little / "
      "medium / large / full (RealEstate10K: the first 76 / 304 / 1216 / all 4866 chunk files in name order, "
      "1,202 / 4,121 / 16,449 / 66,033 scenes; an LVSM-layout split takes that many scenes in list order), "
      "or --chunks N / --scenes N");
  struct Args {
    std::string data, split = "train", name, out;
    int64_t chunks = 0, scenes = 0;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("--data", a->data, "dataset root (chunks or LVSM layout)")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--split", a->split, "split")->capture_default_str();
  auto* name = cmd->add_option("--subset", a->name, "little, medium, large or full")
                   ->check(CLI::IsMember({"little", "medium", "large", "full"}));
  auto* chunks = cmd->add_option("--chunks", a->chunks, "custom: the first N chunk files")->check(CLI::PositiveNumber);
  auto* scenes = cmd->add_option("--scenes", a->scenes, "custom: the first N scenes")->check(CLI::PositiveNumber);
  name->excludes(chunks)->excludes(scenes);
  chunks->excludes(scenes);
  cmd->add_option("--out", a->out, "manifest JSON to write")->required();
  cmd->callback([a] {
    if (a->name.empty() && a->chunks == 0 && a->scenes == 0)
      throw std::runtime_error("dataset subset: give --subset NAME, --chunks N or --scenes N");
    data::ChunkDataset dataset(a->data, a->split);
    const auto m = data::select_subset(dataset, {a->name, a->chunks, a->scenes});
    data::write_subset_manifest(a->out, m);
    std::cout << fmt::format("subset {}: {} scenes{} of {} ({}) -> {}\n", m.name, m.scenes.size(),
                             m.chunks.empty() ? "" : fmt::format(" in {} chunks", m.chunks.size()), dataset.size(),
                             m.rule, a->out);
    if (m.official_scenes > 0 && static_cast<int64_t>(m.scenes.size()) != m.official_scenes)
      std::cout << fmt::format("note: the official {} subset of RealEstate10K has {} scenes; this dataset gives {}\n",
                               m.name, m.official_scenes, m.scenes.size());
  });
}

}  // namespace

void add_dataset_command(CLI::App& app) {
  auto* dataset = app.add_subcommand(
      "dataset",
      "Dataset tools: convert (chunks <-> LVSM layout), stats, subset (little/medium/large/full manifests), import "
      "(your own photos)");
  dataset->require_subcommand(1);
  add_convert(*dataset);
  add_stats(*dataset);
  add_subset(*dataset);
  add_dataset_import_command(*dataset);
}

}  // namespace uplvsm::cli
