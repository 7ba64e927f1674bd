// Pose sensitivity: does the decoder use the latent pose it is given? Per scene (context frames {0, gap}, every frame
// in [0, gap] a target, the inputs included) each view j is rendered twice from the same scene latents: at its own
// pose (from the chosen source: the estimator, the mapper or the dataset) and at the first input's pose. The render
// change mean|R(p_j) - R(p_0)| is set against the truth change mean|I_j - I_0| for the same camera motion:
// sensitivity = sum of render changes / sum of truth changes over the views j != 0. A decoder that ignores the pose
// scores 0; one that moves the image as much as the camera does, about 1. The same pass scores the renders (PSNR,
// gradient-energy ratio), the input views apart: they are what the scene latents hold at best, a ceiling that tells
// a blurry latent representation from a pose that carries no geometry.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "uplvsm/data/chunk_dataset.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::study {

struct SensitivityOptions {
  int64_t max_scenes = 0;  // 0: every scene of the split
  int64_t gap = 12;        // context frames {0, gap} (clamped to the scene length)
  model::TargetPoses source = model::TargetPoses::Estimator;
  torch::Device device = torch::kCPU;
};

struct SensitivityView {
  std::string scene;
  int64_t frame = 0;
  bool input = false;        // one of the two context views
  double psnr = 0;           // of the render at its own pose
  double grad_ratio = 0;     // eval::gradient_energy_ratio of that render
  double render_change = 0;  // mean |R(p_j) - R(p_0)| over pixels and channels
  double truth_change = 0;   // mean |I_j - I_0|
};

struct SensitivityReport {
  std::vector<SensitivityView> views;
  int64_t skipped_scenes = 0;  // too few frames or a bad frame (logged)
};

// Runs the model (eval mode, no gradients) over the first max_scenes scenes of `dataset`.
SensitivityReport measure_pose_sensitivity(model::UPLVSM& net, const data::ChunkDataset& dataset,
                                           const data::PreprocessOptions& prep, const SensitivityOptions& options);

// sensitivity (all views but the first input, and the targets alone), the inputs' and the targets' mean PSNR and
// gradient-energy ratio, view counts.
nlohmann::json summarise(const SensitivityReport& report);

// scene,frame,input,psnr,grad_ratio,render_change,truth_change (one row per view).
void write_sensitivity_csv(const std::string& path, const SensitivityReport& report);

}  // namespace uplvsm::study
