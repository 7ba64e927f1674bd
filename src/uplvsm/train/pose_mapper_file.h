// A pose mapper kept apart from the model it was fitted to (`uplvsm fit-mapper`): a small safetensors file with the
// mapper's tensors under "pose_mapper.*" and, in its metadata, the format, the mapper's kind and width, the
// fingerprint of the model's weights (a mapper speaks one model's latent poses only) and the fit's report. The
// model file is never changed; `--mapper FILE` attaches the mapper at load time.
#pragma once
#include <torch/torch.h>

#include <nlohmann/json.hpp>
#include <string>

#include "uplvsm/model/pose_mapper.h"
#include "uplvsm/model/uplvsm.h"

namespace uplvsm::train {

inline constexpr const char* kPoseMapperFormat = "uplvsm-pose-mapper-v1";

struct PoseMapperFile {
  model::PoseMapper mapper{nullptr};
  std::string model_fingerprint;  // of the model the mapper was fitted to
  nlohmann::json fit;             // what fit-mapper recorded (scenes, steps, losses, seconds)
};

// A digest of the model's weights without its pose mapper (names and float32 values), the same for a model loaded
// from the authors' .pt, its safetensors conversion or our checkpoint of the same weights.
std::string model_fingerprint(model::UPLVSMImpl& net);

void write_pose_mapper_file(const std::string& path, model::PoseMapperImpl& mapper, const std::string& fingerprint,
                            const nlohmann::json& fit);
// Throws naming the file and what is wrong: not a mapper file, unknown kind, missing or mis-shaped tensors.
PoseMapperFile read_pose_mapper_file(const std::string& path);
// Reads `path` and gives its mapper to `net`; an error when it was fitted to another model (fingerprints differ).
void attach_pose_mapper_file(model::UPLVSMImpl& net, const std::string& path);

}  // namespace uplvsm::train
