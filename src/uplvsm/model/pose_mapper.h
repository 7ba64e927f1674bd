// Camera control (paper appendix, "Camera Control"): a linear map C = A·Ĉ + b (A 7x7, b 7) from a real camera pose
// Ĉ to the learned 7-D latent pose C that the decoder understands. Real poses are given relative to the first input
// view (first view canonical, as in the paper) with translations in units of the input baseline |t_in1 - t_in0|, so
// one mapper serves scenes of any metric scale; photos without poses use the same units (baseline = 1).
// The output quaternion is re-normalised like the estimator's. Initialisation: a least-squares fit of the
// estimator's latent poses against real poses on calibration views (fit_pose_mapper), then fine-tuning.
#pragma once
#include <torch/torch.h>

namespace uplvsm::model {

// Real 7-D poses (t, q_xyzw) of `c2w` [b, v, 4, 4] relative to input view 0 of `input_c2w` [b, vi, 4, 4], with
// translations divided by the baseline between input views 0 and 1 (1 when there is one input view or the two
// coincide). Computed in float64, returned as float32.
torch::Tensor camera_control_poses(const torch::Tensor& input_c2w, const torch::Tensor& c2w);
// The inverse: camera-control poses [b, v, 7] back to world c2w [b, v, 4, 4] (float32) in the frame of `input_c2w`
// [b, vi, 4, 4] (how the posed models, which read world cameras, follow a camera path).
torch::Tensor camera_control_to_world(const torch::Tensor& input_c2w, const torch::Tensor& poses);

struct PoseMapperImpl : torch::nn::Module {
  PoseMapperImpl();  // A = identity, b = 0 until fitted
  // real poses [..., 7] -> latent poses [..., 7]
  torch::Tensor forward(const torch::Tensor& real_poses);
  torch::Tensor A, b;  // registered as "A" [7, 7] and "b" [7]
};
TORCH_MODULE(PoseMapper);

// Least-squares fit of A and b so that A·real + b ≈ latent over N pairs ([N, 7] each), ridge-regularised by `ridge`
// (relative to the data's scale) so that a few calibration views still give a well-posed system. Returns the RMS
// residual of the fit.
double fit_pose_mapper(PoseMapperImpl& mapper, const torch::Tensor& real, const torch::Tensor& latent,
                       double ridge = 1e-4);

}  // namespace uplvsm::model
