// The viewer's one door into the model: everything `uplvsm serve` asks of UP-LVSM goes through this adapter, which
// keeps the rest of serve/ independent of the model's class layout. A scene is encoded once (model/encoded_scene.h:
// the scene latents and the inputs' latent poses, cached by the caller) and each frame rendered from it, at latent
// poses or, when the checkpoint has a camera mapper, at real cameras through it.
#pragma once
#include <torch/torch.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

#include "uplvsm/core/config.h"
#include "uplvsm/data/preprocess.h"
#include "uplvsm/data/scene.h"
#include "uplvsm/model/encoded_scene.h"

namespace uplvsm::model {
struct UPLVSMImpl;
}

namespace uplvsm::serve {

// How a 7-D camera pose (t, q_xyzw) is meant: a latent pose the decoder reads directly, or a real camera relative
// to input view 0 in input baselines (camera-control units), turned into a latent pose by the mapper.
enum class PoseSpace { Latent, Real };
PoseSpace parse_pose_space(const std::string& name);  // "latent" | "real"; throws std::invalid_argument
const char* to_string(PoseSpace space);

// One scene as the decoder needs it, computed once (latents, input_poses, height, width), with what the viewer shows
// of it.
struct SceneEncoding : model::EncodedScene {
  torch::Tensor key_latent;  // [2, 7] float64 CPU: the estimator's latent poses of the two inputs (input_poses)
  torch::Tensor key_real;    // [2, 7] float64 CPU: the inputs in camera-control units (undefined without a mapper)
  bool key_real_estimated = false;  // key_real[1] inverted through the mapper (photos without cameras)
  // How far the mapper at key_real[1] stays from key_latent[1] (RMS, latent units; NaN unless estimated): near 0, a
  // render there is the estimator's render of the photo; large, no real camera reaches what the estimator read.
  double key_real_residual = NAN;
  torch::Tensor fxfycxcy;  // [4] float32 pixels: input 0's intrinsics, used for every rendered frame
  int64_t bytes() const;   // memory held (latents and poses; input_poses counted as key_latent)
};

class ViewerModel {
 public:
  // Loads any UP-LVSM checkpoint `uplvsm` reads (ours or the authors'; `config_hint`: optional config JSON for
  // official files). Posed variants are refused: the viewer starts from unposed photos. `mapper`: a pose mapper file
  // fitted to the checkpoint (fit-mapper), attached for real cameras; empty: the checkpoint's own, if any.
  static ViewerModel load(const std::string& checkpoint, const std::string& config_hint, torch::Device device,
                          bool bf16, const std::string& mapper = "");
  // A model already built (tests, benchmarks).
  ViewerModel(std::shared_ptr<model::UPLVSMImpl> net, Config config, bool bf16);

  int64_t image_size() const { return config_.model.image_size; }
  int64_t patch_size() const { return config_.model.patch_size; }
  bool has_mapper() const;
  bool bf16() const { return bf16_; }
  int64_t parameter_count() const;
  const Config& config() const { return config_; }
  // The preprocessing of the viewer's scenes and uploads: the model's sizes, square frames.
  data::PreprocessOptions preprocess_options() const { return data::square_preprocess_options(config_); }

  // views: images [2, 3, H, W] in [0, 1], fxfycxcy [2, 4] pixels, c2w [2, 4, 4] when `posed` (dataset cameras).
  // Runs the encoder and the estimator. Not thread-safe with other calls: callers serialise model use.
  SceneEncoding encode(const data::SceneViews& views, bool posed) const;
  // poses [F, 7] in `space` -> frames [F, 3, H, W] float32 CPU in [0, 1]. Only the decoder runs.
  torch::Tensor render(const SceneEncoding& scene, const torch::Tensor& poses, PoseSpace space) const;

 private:
  void place_second_photo(SceneEncoding& scene) const;

  std::shared_ptr<model::UPLVSMImpl> net_;
  Config config_;
  bool bf16_ = false;
  torch::Device device_{torch::kCPU};
};

}  // namespace uplvsm::serve
