// `uplvsm make-dataset`: renders the built-in room walkthroughs or objects into the pixelSplat chunk format.
#include <chrono>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "uplvsm/cli/commands.h"
#include "uplvsm/core/config.h"
#include "uplvsm/data/synthetic/object_scenes.h"
#include "uplvsm/data/synthetic/room_scenes.h"

namespace uplvsm::cli {

namespace {

data::SceneGenerator scene_generator(const DatasetConfig& c) {
  if (c.kind == "objects") {
    data::ObjectSceneOptions opt;
    opt.height = static_cast<int>(c.render_height);
    opt.width = static_cast<int>(c.render_width);
    opt.views = static_cast<int>(c.frames_per_scene);
    opt.texture_scale = c.texture_scale;
    return data::object_generator(opt);
  }
  return data::room_generator(data::room_scene_options(c));
}

}  // namespace

void add_make_dataset_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "make-dataset",
      "Render a built-in multi-view dataset with exact cameras into pixelSplat chunks: <out>/{train,test}/*.torch + "
      "index.json, <out>/evaluation_index.json, <out>/dataset.json. --kind rooms: textured rooms seen along "
      "RealEstate10K-like camera walks (ordered frames); --kind objects: one textured object per scene seen from "
      "random cameras on a sphere, Objaverse-like (unordered views).");
  struct Args {
    CommonOptions common;
    std::string config, out, kind;
    int64_t train = -1, test = -1, seed = -1;
  };
  auto a = std::make_shared<Args>();
  add_common_options(cmd, a->common);
  cmd->add_option("--config", a->config, "config JSON whose 'dataset' section sets sizes")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", a->out, "dataset root to write")->required();
  cmd->add_option("--train-scenes", a->train, "override dataset.num_train_scenes");
  cmd->add_option("--test-scenes", a->test, "override dataset.num_test_scenes");
  cmd->add_option("--seed", a->seed, "override dataset.seed");
  cmd->add_option("--kind", a->kind, "override dataset.kind: rooms or objects")
      ->check(CLI::IsMember({"rooms", "objects"}));
  cmd->callback([a] {
    apply_common_options(a->common);
    auto c = load_config(a->config).dataset;
    if (a->train >= 0) c.num_train_scenes = a->train;
    if (a->test >= 0) c.num_test_scenes = a->test;
    if (a->seed >= 0) c.seed = a->seed;
    if (!a->kind.empty()) c.kind = a->kind;
    auto t0 = std::chrono::steady_clock::now();
    spdlog::info("rendering {} train + {} test {} scenes of {} frames at {}x{} into {}", c.num_train_scenes,
                 c.num_test_scenes, c.kind, c.frames_per_scene, c.render_width, c.render_height, a->out);
    data::write_generated_dataset(a->out, static_cast<int>(c.num_train_scenes), static_cast<int>(c.num_test_scenes),
                                  static_cast<uint64_t>(c.seed), scene_generator(c));
    std::cout << fmt::format("dataset written to {} in {:.1f} s\n", a->out,
                             std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  });
}

}  // namespace uplvsm::cli
