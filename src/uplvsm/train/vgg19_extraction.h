// The perceptual loss's VGG19 that the authors' checkpoints carry, written beside a converted checkpoint so a later
// `uplvsm train --vgg19` can use the very weights the official recipe trained with.
#pragma once
#include <cstdint>
#include <string>

#include "uplvsm/io/pretrained_weights.h"

namespace uplvsm::train {

struct VggExtraction {
  int64_t tensors = 0;  // 0: the weights held no VGG19, nothing written
  std::string path;     // <output stem>.vgg19.safetensors
};

// The VGG19 features of `weights` (MatConvNet ImageNet weights), saved under torchvision's `features.N` names, the
// format the perceptual loss reads, and marked as taking MatConvNet's input; the untrained classifier and the
// aliased `blocks.*` keys are left out.
VggExtraction write_vgg19_extras(const io::PretrainedWeights& weights, const std::string& output);

}  // namespace uplvsm::train
