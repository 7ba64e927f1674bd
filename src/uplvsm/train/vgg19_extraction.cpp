#include "uplvsm/train/vgg19_extraction.h"

#include <filesystem>

#include "uplvsm/io/safetensors.h"
#include "uplvsm/train/perceptual_loss.h"

namespace uplvsm::train {

VggExtraction write_vgg19_extras(const io::PretrainedWeights& weights, const std::string& output) {
  io::TensorMap vgg;
  const std::string prefix = "loss_computer.perceptual_loss_module.vgg.";
  for (const auto& [k, v] : weights.tensors)
    if (k.rfind(prefix + "features.", 0) == 0) vgg[k.substr(prefix.size())] = v.contiguous();
  if (vgg.empty()) return {};
  VggExtraction r;
  r.tensors = static_cast<int64_t>(vgg.size());
  r.path = std::filesystem::path(output).replace_extension(".vgg19.safetensors").string();
  // Marked, so the perceptual loss prepares MatConvNet's input for them (train/perceptual_loss.h).
  io::write_safetensors(r.path, vgg,
                        {{"source", weights.path},
                         {"content", "VGG19 features of the perceptual loss"},
                         {kVggInputMetadataKey, to_string(VggInput::MatConvNet)}});
  return r;
}

}  // namespace uplvsm::train
