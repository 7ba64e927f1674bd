// Camera control for a frozen model (`uplvsm fit-mapper`): a pose mapper fitted to a trained UP-LVSM from posed
// scenes, the model's weights unchanged. The model gives, for each posed target view, the latent pose its estimator
// reads from the image; the mapper is fitted to reproduce it from the view's real camera (camera-control units):
// the linear mapper by least squares, the MLP mapper from there by full-batch Adam on the same pairs (pose space:
// no model in the loop, seconds), whole scenes held out of it (and of its least-squares start) to keep the best of
// its checks. Training the mapper through the frozen renderer instead was measured and lost
// (docs/research/camera-control.md). `train --stage mapper` fine-tunes the whole model through its mapper instead.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/loader.h"
#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::train {

struct MapperFitOptions {
  int64_t calibration_views = 24000;  // posed target views the mapper is fitted on
  int64_t regression_steps = 4000;    // MLP: full-batch Adam steps (linear warmup, cosine decay)
  double regression_lr = 1e-2;
  data::LoaderOptions loader;  // the scenes (max_scenes: the first N), views and samples per batch
  torch::Device device = torch::kCPU;
  bool bf16 = false;  // the frozen model's forward under bf16 autocast (the mapper stays fp32)
};

struct MapperFitReport {
  int64_t scenes = 0;               // posed scenes the fit could draw from
  int64_t calibration_views = 0;    // (real pose, latent pose) pairs fitted
  double least_squares_rms = 0;     // the linear fit's residual, latent units
  double fit_rms = 0;               // the fitted mapper's residual (the MLP's after its steps; else the linear one's)
  double held_out_rms = NAN;        // MLP: on the held-out scenes' views (NaN: no scene held out)
  double start_held_out_rms = NAN;  // MLP: the same for its least-squares start (the kept map is never worse)
  std::vector<std::string> held_out_scenes;  // MLP: the keys of the scenes held out (held_out_scene) that were drawn
  int64_t held_out_views = 0;
  int64_t skipped_samples = 0;  // samples whose two inputs coincide (no baseline to measure in)
  double seconds = 0;
  nlohmann::json to_json() const;
};

// Whether scene `scene` of the first `scenes` is held out of an MLP mapper's fit to check it (the linear map reads
// every scene): every tenth (9, 19, ...), the last of 2 to 9 scenes, none of one.
bool held_out_scene(int64_t scene, int64_t scenes);

// Fits `mapper` (any kind; moved to options.device) to `net`, whose weights it only reads. Scenes without cameras
// (unposed.json) are an error naming them; samples whose inputs coincide are skipped and counted (all of them: an
// error).
MapperFitReport fit_mapper_to_model(model::UPLVSMImpl& net, model::PoseMapperImpl& mapper,
                                    const data::ChunkDataset& dataset, const MapperFitOptions& options);

}  // namespace uplvsm::train
