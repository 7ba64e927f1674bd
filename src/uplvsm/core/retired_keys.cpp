#include "uplvsm/core/retired_keys.h"

#include <stdexcept>
#include <vector>

#include <fmt/format.h>

#include "uplvsm/core/json_input.h"

namespace uplvsm {

namespace {

constexpr const char* kIssue62 = "d3badc2";
constexpr const char* kIssue70 = "8ca59b4";

// Section, key, the default it had (the lever off), the last commit with its code.
const std::vector<RetiredKey>& retired_keys() {
  static const std::vector<RetiredKey> keys{
      {"model", "estimator_half_view", false, kIssue62},
      {"model.transformer", "identity_rotation_init", false, kIssue62},
      {"model.transformer", "latent_rotation_gain", 1.0, kIssue62},
      {"model.transformer", "latent_pivot_depth", 0.0, kIssue62},
      {"model.transformer", "estimator_correspondence", false, kIssue62},
      {"model.transformer", "pose_error_feedback_steps", 0, kIssue62},
      {"training", "l1_loss_weight", 0.0, kIssue62},
      {"training", "ssim_loss_weight", 0.0, kIssue62},
      {"training", "ema_decay", 0.0, kIssue62},
      {"training", "rotation_equivariance_weight", 0.0, kIssue62},
      {"training", "rotation_equivariance_degrees", 10.0, kIssue62},
      {"training", "turned_view_weight", 0.0, kIssue62},
      {"training", "turned_view_degrees", 10.0, kIssue62},
      {"training", "rotation_alignment_weight", 0.0, kIssue62},
      {"training", "rotation_alignment_blur", 0.0, kIssue62},
      {"training", "latent_translation_warmup_steps", 0, kIssue62},
      {"training", "latent_translation_weight", 0.0, kIssue62},
      {"training", "init_new_blocks_identity", false, kIssue62},
      {"training", "fitted_pose_steps", 0, kIssue62},
      {"training", "fitted_pose_lr", 1e-2, kIssue62},
      {"training", "fitted_pose_weight", 1.0, kIssue62},
      {"training", "render_at_fitted_poses", true, kIssue62},
      {"eval", "num_target_views", 3, kIssue62},  // read from configs, never used
      // N(0, value) on all views before the scene normalisation: no equal in the official knob.
      {"training", "pose_noise_variance", 0.0, kIssue62,
       "replaced by training.pose_noise_std, the official noise_scale: a standard deviation, drawn after the "
       "scene normalisation and apart for inputs and targets (the old noise was sd sqrt(value) on all views "
       "before it)"},
      // It made UP-LVSM two models in one class (issue 70).
      {"model", "encoder_cameras", false, kIssue70,
       "a diagnostic (LVSM's encoder-decoder told every input camera) kept until it had measured the architecture's "
       "share of UP-LVSM's gap (docs/research/demo-history.md)"},
  };
  return keys;
}

}  // namespace

const RetiredKey* find_retired_key(const std::string& section, const std::string& key) {
  for (const auto& r : retired_keys())
    if (section == r.section && key == r.key) return &r;
  return nullptr;
}

std::string retired_key_note(const RetiredKey& r) {
  return fmt::format("{}.{} was retired: {}; its code is at commit {} (git show {}), the last version that reads it",
                     r.section, r.key, r.why ? r.why : "it measured no gain (docs/research/levers.md)", r.commit,
                     r.commit);
}

bool accept_retired_key(const std::string& section, const std::string& key, const nlohmann::json& value,
                        const std::string& where) {
  const RetiredKey* r = find_retired_key(section, key);
  if (!r) return false;
  // nlohmann compares numbers by value across integer and floating types: 0 == 0.0, 1 == 1.0.
  if (value == r->default_value) return true;
  throw std::runtime_error(fmt::format("{}: '{}' is {}, not its default {}: {}", where, key, json_excerpt(value),
                                       r->default_value.dump(), retired_key_note(*r)));
}

}  // namespace uplvsm
