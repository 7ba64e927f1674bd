// Whether a model written to a checkpoint comes back as it was: `uplvsm convert --verify` reloads what it wrote,
// compares every tensor and runs one forward pass, so a conversion that loses or corrupts weights fails at once
// rather than hours into a run.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <torch/torch.h>

#include "uplvsm/model/novel_view_model.h"

namespace uplvsm::model {

struct RoundTripCheck {
  int64_t tensors = 0;     // identical after the reload
  int64_t image_size = 0;  // of the forward pass, square
  double seconds = 0;      // the forward pass's
  double render_mean = 0;
  std::vector<float> pose;  // the first 7 numbers of the pose encoding (zeros for a model without one)
};

// Reloads `path` on `device`, checks each tensor equals `written`'s and that a forward pass of 2 random inputs and 1
// target is finite; throws naming the tensor that changed, or the NaN/Inf.
RoundTripCheck check_round_trip(const std::string& path, const NovelViewModelImpl& written,
                                const torch::Device& device);

}  // namespace uplvsm::model
