// The Python module's one view of the model classes: everything `uplvsm.Model` does goes through this adapter, so a
// change in the model family (model/novel_view_model.h, model/uplvsm.h) touches this file and model_adapter.cpp
// only. The family's interface renders targets from inputs for any model; scene latents and latent poses are
// UP-LVSM's (model::require_uplvsm names the model when asked of another). Tensors in and out are
// the callers' own (no copies on the model's device); the methods never touch Python objects, so the bindings run
// them with the GIL released.
#pragma once
#include <torch/torch.h>

#include <optional>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/model/novel_view_model.h"
#include "uplvsm/model/uplvsm.h"
#include "uplvsm/render/renderer.h"

namespace uplvsm::python {

struct ForwardResult {
  torch::Tensor render;  // [b, v_t, 3, H, W]
  torch::Tensor poses;   // [b, v_t, 7] latent poses; undefined for the posed variants
};

class ModelAdapter {
 public:
  // Any weight file model::load_model reads; `hint` is the config for an authors' file (ignored for ours).
  ModelAdapter(const std::string& path, const torch::Device& device, const Config* hint);
  // A freshly initialised model of `config` (random weights from `seed`, in eval mode): training from scratch,
  // benchmarks.
  ModelAdapter(const Config& config, const torch::Device& device, uint64_t seed);

  const Config& config() const { return config_; }
  torch::Device device() const { return device_; }
  std::string name() const { return net_->name(); }  // "UP-LVSM", "PT-LVSM", "LVSM"
  int64_t parameter_count() const;
  // Parameters and buffers under their checkpoint names, detached but sharing the model's memory.
  std::vector<std::pair<std::string, torch::Tensor>> state_dict() const;

  torch::Tensor encode_scene(const torch::Tensor& images, const torch::Tensor& fxfycxcy, const std::string& amp);
  torch::Tensor estimate_poses(const torch::Tensor& target_images, const torch::Tensor& scene_latents,
                               const std::string& amp);
  torch::Tensor render_views(const torch::Tensor& scene_latents, const torch::Tensor& poses,
                             const torch::Tensor& fxfycxcy, int64_t height, int64_t width, const std::string& amp);
  // target_poses: "auto" | "estimator" | "mapper" | "dataset" (parse_target_poses).
  ForwardResult forward(const model::Views& inputs, const model::Views& targets, const std::string& target_poses,
                        const std::string& amp);
  render::InterpolationVideo render_interpolation(const torch::Tensor& images, const torch::Tensor& fxfycxcy,
                                                  int64_t num_frames, int64_t chunk, const std::string& amp);
  torch::Tensor render_camera_path(const data::SceneViews& inputs, const torch::Tensor& poses,
                                   const torch::Tensor& fxfycxcy, int64_t chunk, const std::string& amp);

 private:
  // UP-LVSM's own capabilities (scene latents, latent poses): an error naming `what` for the other models.
  model::UPLVSM unposed(const char* what) const;
  torch::Tensor on_device(const torch::Tensor& t) const;

  Config config_;
  torch::Device device_;
  model::NovelViewModel net_{nullptr};
};

}  // namespace uplvsm::python
