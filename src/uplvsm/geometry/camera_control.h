// Camera-control units (paper appendix, "Camera Control"): real camera poses relative to the first input view (first
// view canonical) with translations in units of the input baseline |t_in1 - t_in0|, so that one pose mapper serves
// scenes of any metric scale; photos without poses use the same units (baseline = 1).
#pragma once
#include <torch/torch.h>

namespace uplvsm::geometry {

// Real 7-D poses (t, q_xyzw) of `c2w` [b, v, 4, 4] relative to input view 0 of `input_c2w` [b, vi, 4, 4], with
// translations divided by the baseline between input views 0 and 1 (1 when there is one input view or the two
// coincide). Computed in float64, returned as float32.
torch::Tensor camera_control_poses(const torch::Tensor& input_c2w, const torch::Tensor& c2w);
// The inverse: camera-control poses [b, v, 7] back to world c2w [b, v, 4, 4] (float32) in the frame of `input_c2w`
// [b, vi, 4, 4] (how the posed models, which read world cameras, follow a camera path).
torch::Tensor camera_control_to_world(const torch::Tensor& input_c2w, const torch::Tensor& poses);

}  // namespace uplvsm::geometry
