#include "uplvsm/eval/eval_pose_noise.h"

#include <fmt/format.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "uplvsm/data/loader.h"
#include "uplvsm/geometry/camera.h"

namespace uplvsm::eval {

void check_pose_noise_std(double std) {
  if (!(std >= 0) || !std::isfinite(std))
    throw std::invalid_argument(
        fmt::format("--pose-noise-std: expected a finite number >= 0 (the official noise_scale, a standard deviation "
                    "of the (t, q) pose encoding; 0: clean test cameras), got {}",
                    std));
}

bool pose_noise_reaches_model(model::TargetPoses target_poses) { return target_poses != model::TargetPoses::Estimator; }

uint64_t pose_noise_scene_seed(uint64_t seed, const std::string& key) {
  // FNV-1a of the key (stable across builds, unlike std::hash), then a splitmix64 round with the seed.
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char ch : key) h = (h ^ ch) * 0x100000001b3ULL;
  uint64_t z = h + seed * 0x9E3779B97F4A7C15ULL + 0x6576616c6e6f6973ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

ToldCameras noisy_scene_cameras(const torch::Tensor& c2w, int64_t num_inputs, double std, uint64_t seed,
                                const std::string& key) {
  TORCH_CHECK(c2w.dim() == 3 && num_inputs > 0 && num_inputs < c2w.size(0), "pose noise: scene ", key,
              ": expected [inputs + targets, 4, 4] cameras with ", num_inputs, " inputs, got ", c2w.sizes());
  TORCH_CHECK(torch::isfinite(c2w).all().item<bool>(), "pose noise: scene ", key,
              " has no finite dataset cameras to add noise to");
  auto frame = geometry::official_scene_normalize(c2w.to(torch::kFloat32));
  const int64_t vt = c2w.size(0) - num_inputs;
  std::mt19937_64 rng(pose_noise_scene_seed(seed, key));
  // Official order: the inputs' draws, then the targets' (data_utils.py ProcessData.forward).
  auto inputs = data::with_pose_noise(frame.narrow(0, 0, num_inputs), std, rng);
  auto targets = data::with_pose_noise(frame.narrow(0, num_inputs, vt), std, rng);
  return {inputs, targets};
}

nlohmann::json pose_noise_record(double std, uint64_t seed, model::TargetPoses target_poses) {
  if (std == 0) return {{"std", 0.0}, {"reaches_model", false}, {"cameras", "clean dataset cameras"}};
  const bool reaches = pose_noise_reaches_model(target_poses);
  return {{"std", std},
          {"seed", seed},
          {"reaches_model", reaches},
          {"cameras", reaches ? "the input and target dataset cameras the model reads, in the official scene frame, "
                                "with N(0, std^2) on their (t, q_xyzw) encodings, inputs and targets drawn apart "
                                "(the official noise_scale at evaluation); the baselines use clean cameras"
                              : "none: with the estimator's target poses UP-LVSM reads no dataset camera, so the "
                                "noise changes nothing (as in the official code)"}};
}

}  // namespace uplvsm::eval
