// Camera control (paper appendix, "Camera Control"): a map from a real camera pose Ĉ to the learned 7-D latent pose
// C that the decoder understands. The paper's mapper is linear, C = A·Ĉ + b (A 7x7, b 7); the MLP mapper adds a
// small residual network, C = A·Ĉ + b + MLP(Ĉ, s), where s holds the latent poses the estimator reads from the two
// input views (known for every scene, posed or not): they anchor the scene's own latent frame and scale, which a
// map from the real pose alone cannot know.
// Real poses are given relative to the first input view (first view canonical, as in the paper) with translations in
// units of the input baseline |t_in1 - t_in0|, so one mapper serves scenes of any metric scale; photos without poses
// use the same units (baseline = 1). The output quaternion is re-normalised like the estimator's. Initialisation: a
// least-squares fit of the estimator's latent poses against real poses on calibration views (fit_pose_mapper), then
// training (train --stage mapper fine-tunes the model with it; fit-mapper trains the mapper alone).
#pragma once
#include <torch/torch.h>

#include <string>

namespace uplvsm::model {

enum class PoseMapperKind { Linear, Mlp };
std::string to_string(PoseMapperKind kind);
PoseMapperKind parse_pose_mapper_kind(const std::string& name);  // "linear" | "mlp", else an error naming both

struct PoseMapperOptions {
  PoseMapperKind kind = PoseMapperKind::Linear;
  int64_t hidden = 128;  // the MLP's width (two hidden layers)
};

// What the MLP mapper reads of a scene besides the target's real pose: [b, 14], the estimator's latent poses of input
// views 0 and 1 (scene_conditioning()).
inline constexpr int64_t kSceneConditioningDims = 14;

struct PoseMapperImpl : torch::nn::Module {
  explicit PoseMapperImpl(PoseMapperOptions options = {});  // A = identity, b = 0, the MLP's output zero
  // real poses [b, n, 7] (or [n, 7]) -> latent poses of the same shape; `scene` [b, 14] (MLP only; required there)
  torch::Tensor forward(const torch::Tensor& real_poses, const torch::Tensor& scene = {});
  bool reads_scene() const { return options.kind == PoseMapperKind::Mlp; }

  PoseMapperOptions options;
  torch::Tensor A, b;                  // registered as "A" [7, 7] and "b" [7]
  torch::nn::Sequential mlp{nullptr};  // registered as "mlp" for the MLP kind
};
TORCH_MODULE(PoseMapper);

// The MLP mapper's scene input from the estimator's latent poses of the inputs [b, vi, 7]: views 0 and 1 ([b, 14]; view
// 0 twice with a single input view).
torch::Tensor scene_conditioning(const torch::Tensor& input_latent_poses);

// Least-squares fit of A and b so that A·real + b ≈ latent over N pairs ([N, 7] each), ridge-regularised by `ridge`
// (relative to the data's scale) so that a few calibration views still give a well-posed system. Returns the RMS
// residual of the fit.
double fit_pose_mapper(PoseMapperImpl& mapper, const torch::Tensor& real, const torch::Tensor& latent,
                       double ridge = 1e-4);

// The real pose of input view 1 (camera-control units: |t| = 1 baseline, |q| = 1) that `mapper` maps nearest to
// `latent` [7] (the estimator's latent pose of that view; `scene` [1, 14] for the MLP kind): how the viewer places a
// photo that has no camera. Levenberg-Marquardt on (t, q) through the normalisation, with the mapper's Jacobian by
// autograd, from the linear map's inverse and from that rotation at each of the six axis directions (the best end
// kept): a map whose MLP part is as steep as its linear part defeats a fixed-point iteration on A^-1, and a photo
// whose latent pose no real pose reaches must be told rather than placed silently.
struct MapperInverse {
  torch::Tensor real;   // [7] float64 CPU
  double residual = 0;  // RMS of mapper(real) - latent over its 7 components, latent units
};
MapperInverse invert_pose_mapper(PoseMapperImpl& mapper, const torch::Tensor& latent, const torch::Tensor& scene = {});

}  // namespace uplvsm::model
