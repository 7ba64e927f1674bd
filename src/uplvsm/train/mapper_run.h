// `uplvsm fit-mapper` and the set-up of `study mapper-scenes` as library calls: a trained UP-LVSM loaded from its
// checkpoint, the posed scenes sampled as the command's flags say, and a pose mapper fitted to it
// (train/mapper_fitting.h) and saved apart from the model for `render|eval|serve --mapper`. The held-out score of
// the fitted mapper is eval::evaluate_mapper (eval/training_evaluation.h).
#pragma once
#include <torch/torch.h>

#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/train/mapper_fitting.h"

namespace uplvsm::train {

// What fit-mapper and study mapper-scenes share: the model, the posed scenes, the mapper and how it is fitted.
struct MapperRunOptions {
  std::string checkpoint, config;  // the model (config: for an official checkpoint, as --config)
  std::string data, split = "train";
  std::string kind = "mlp";  // "linear" | "mlp"
  int64_t hidden = 128;      // mlp: width of its hidden layers
  bool bf16 = false;         // the frozen model's forward under bf16 autocast
  int64_t batch = 8;         // samples encoded at once
  // 0: the checkpoint's training views (target views per sample, input frame distances), training seed
  int64_t targets = 0, min_frame_dist = 0, max_frame_dist = 0;
  uint64_t seed = 0;
  double pose_noise_std = 0;  // cameras with N(0, S^2) on their (t, q) encoding, as the loader's pose-noise study
  MapperFitOptions fit;       // views, steps, lr (its loader, device and bf16 are set from the fields above)
  torch::Device device = torch::kCPU;
};

// The model to fit a mapper to (an UP-LVSM, else an error), its config and the fit's options for `dataset`.
struct MapperSetup {
  Config config;
  model::NovelViewModel net{nullptr};
  model::UPLVSM up{nullptr};
  MapperFitOptions fit;
};
MapperSetup load_for_mapper_fit(const MapperRunOptions& options, const data::ChunkDataset& dataset);
model::PoseMapperOptions mapper_options(const MapperRunOptions& options);

struct FitMapperOptions : MapperRunOptions {
  std::string out;     // the mapper file to write (safetensors)
  int64_t scenes = 0;  // the split's first N scenes only (0: all)
};

struct FitMapperResult {
  MapperFitReport report;
  MapperSetup model;  // with the fitted mapper attached, for a held-out score
};

// Loads the model, fits the mapper on the posed scenes and saves it (with the fit's report, kind, data and
// checkpoint) to options.out.
FitMapperResult fit_mapper(const FitMapperOptions& options);

}  // namespace uplvsm::train
