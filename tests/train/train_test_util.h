// A micro UP-LVSM config and a tiny built-in dataset for fast training tests.
#pragma once
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_util.h"
#include "uplvsm/core/config.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/synthetic/room_scenes.h"
#include "uplvsm/train/mapper_run.h"
#include "uplvsm/train/trainer.h"

namespace uplvsm::test {

// A micro model of any variant: 32 px, patch 8, d 32, one block per stack (posed variants: n_layer 2).
inline ModelConfig micro_model(const std::string& variant = "uplvsm") {
  ModelConfig m;
  m.variant = parse_variant(variant);
  m.image_size = 32;
  m.patch_size = 8;
  m.transformer.d = 32;
  m.transformer.d_head = 16;
  m.transformer.encoder_n_layer = 1;
  m.transformer.estimator_n_layer = 1;
  m.transformer.decoder_n_layer = 1;
  m.transformer.n_layer = 2;
  m.transformer.n_latent_vectors = 8;
  m.dinov2.embed_dim = 32;
  m.dinov2.depth = 1;
  m.dinov2.num_heads = 2;
  m.dinov2.pos_grid = 4;
  return m;
}

// How micro_model() sees a frame: resized and centre-cropped to 32 x 32, patch 8.
inline data::PreprocessOptions micro_prep() {
  data::PreprocessOptions p;
  p.image_size = 32;
  p.patch_size = 8;
  return p;
}

inline Config micro_config() {
  Config c;
  c.name = "micro";
  c.model = micro_model();
  auto& t = c.training;
  t.lr = 3e-3;
  t.warmup = 2;
  t.train_steps = 40;
  t.batch_size = 2;
  t.num_views = 4;
  t.num_input_views = 2;
  t.num_target_views = 2;
  t.min_frame_dist = 2;
  t.max_frame_dist = 6;
  t.checkpoint_every = 1000;
  t.log_every = 1;
  t.loader_threads = 1;
  c.dataset.frames_per_scene = 12;
  return c;
}

// Six train and two test scenes of 12 frames at 36x64, written once per test binary run.
inline std::string micro_dataset() {
  static std::string root;
  if (root.empty()) {
    root = temp_dir("micro_dataset").string();
    data::RoomSceneOptions opt;
    opt.height = 36;
    opt.width = 64;
    opt.frames = 12;
    data::write_builtin_dataset(root, 6, 2, 5, opt);
  }
  return root;
}

// Trainer options for a run of micro_dataset() into `run`, without a progress bar.
inline train::TrainOptions micro_run_options(const std::string& run) {
  train::TrainOptions o;
  o.data_root = micro_dataset();
  o.run_dir = run;
  o.progress = false;
  return o;
}

// A one-step micro UP-LVSM trained into <dir>/run, and options that fit a linear mapper to it on micro_dataset()
// (3 targets a scene, 3 scenes a batch).
inline train::MapperRunOptions micro_mapper_run(const std::filesystem::path& dir, int64_t calibration_views) {
  auto config = micro_config();
  config.training.train_steps = 1;
  const auto run = (dir / "run").string();
  if (train::train(config, micro_run_options(run)).last_checkpoint.empty())
    throw std::runtime_error("micro_mapper_run: the one-step run wrote no checkpoint");
  train::MapperRunOptions o;
  o.checkpoint = run;
  o.data = micro_dataset();
  o.kind = "linear";
  o.batch = 3;
  o.targets = 3;
  o.min_frame_dist = 2;
  o.max_frame_dist = 6;
  o.fit.calibration_views = calibration_views;
  return o;
}

// One field of every step line of a run's metrics.jsonl (lines without it, such as evaluations, are skipped).
inline std::vector<double> logged(const std::string& run, const std::string& field = "loss") {
  std::vector<double> out;
  std::ifstream in(std::filesystem::path(run) / "metrics.jsonl");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const auto j = nlohmann::json::parse(line);
    if (j.contains(field)) out.push_back(j.at(field).get<double>());
  }
  return out;
}

}  // namespace uplvsm::test
