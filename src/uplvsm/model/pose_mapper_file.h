// A fitted pose mapper in and out of a model: written to its own file (the format: io/pose_mapper_file.h) with the
// fingerprint of the model it was fitted to, read back into a PoseMapper, attached to a model only when the
// fingerprints agree. The model file is never changed; `--mapper FILE` attaches the mapper at load time.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::model {

struct LoadedPoseMapper {
  PoseMapper mapper{nullptr};
  std::string model_fingerprint;  // of the model the mapper was fitted to
  nlohmann::json fit;             // what fit-mapper recorded (scenes, steps, losses, seconds)
};

// A digest of the model's weights without its pose mapper (names and float32 values), the same for a model loaded
// from the authors' .pt, its safetensors conversion or our checkpoint of the same weights.
std::string model_fingerprint(UPLVSMImpl& net);

void save_pose_mapper(const std::string& path, PoseMapperImpl& mapper, const std::string& fingerprint,
                      const nlohmann::json& fit);
// Throws naming the file and what is wrong: not a mapper file, unknown kind, missing or mis-shaped tensors.
LoadedPoseMapper load_pose_mapper(const std::string& path);
// Reads `path` and gives its mapper to `net`; an error when it was fitted to another model (fingerprints differ).
void attach_pose_mapper_file(UPLVSMImpl& net, const std::string& path);

}  // namespace uplvsm::model
