// Camera control (paper appendix, "Camera Control"): a linear map C = A·Ĉ + b (A 7x7, b 7) from a real camera pose
// Ĉ to the learned 7-D latent pose C that the decoder understands. Real poses are given relative to the first input
// view (first view canonical, as in the paper) with translations in units of the input baseline |t_in1 - t_in0|, so
// one mapper serves scenes of any metric scale; photos without poses use the same units (baseline = 1).
// The output quaternion is re-normalised like the estimator's. Initialisation: a least-squares fit of the
// estimator's latent poses against real poses on calibration views (fit_pose_mapper), then fine-tuning.
#pragma once
#include <torch/torch.h>

namespace uplvsm::model {

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
